"""Agent ppo_finetune: Track A's last stage, RL fine-tuning of a bc_dagger student with Stable-Baselines3's PPO.

The policy starts as the student, exactly (its observation normaliser, its MLP and its tanh output): PPO's
actor is the student's network with gSDE noise (state-dependent, resampled every `sde_sample_freq` steps, so
that the joints' PD loops do not filter it out) before the tanh (`squash_output`), so the deterministic
action is the student's own at the start. The critic is new (an MLP of the same shape): for the first
`frozen_policy_updates` updates only the critic learns, the actor is held, so that PPO's first steps follow
advantages from a fitted value rather than a random one. Everything else is the sb3 agents' (DeepTrainer:
episodes.csv, checkpoints, resume, the run's files; robot_rl.agents.sb3.policy plays the run).

The run is teacher-initialised: what it knows at the start it learned from the controller by BC and DAgger.
"""
from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from robot_rl import DEEP_CHECKPOINT, DeepTrainer, ParamError, PpoParams, RunFileError, package_path, param

from .student import NumpyStudent


class Normalise(BaseFeaturesExtractor):
    """The student's observation normaliser, (observation - mean) / std, as buffers: saved with the weights,
    set from the student at the start (zeros and ones until then)."""

    mean: torch.Tensor
    std: torch.Tensor

    def __init__(self, observation_space: gymnasium.spaces.Box):
        size = int(np.prod(observation_space.shape))
        super().__init__(observation_space, size)
        self.register_buffer("mean", torch.zeros(size))
        self.register_buffer("std", torch.ones(size))

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return (observations.flatten(1) - self.mean) / self.std


class FinetunePPO(PPO):
    """SB3's PPO whose actor (the policy network, its action layer and its noise) is held while the run's env
    steps are at most `frozen_policy_steps`: only the critic learns then. Counted in env steps (num_timesteps,
    which a resume restores), so a resumed run does not freeze its actor again; make_trainer sets it."""

    frozen_policy_steps: int = 0

    def actor_parameters(self) -> list[torch.nn.Parameter]:
        policy = self.policy
        assert isinstance(policy, ActorCriticPolicy)
        return [*policy.mlp_extractor.policy_net.parameters(), *policy.action_net.parameters(), policy.log_std]

    def train(self) -> None:
        frozen = self.num_timesteps <= self.frozen_policy_steps
        for parameter in self.actor_parameters():
            parameter.requires_grad_(not frozen)
        super().train()


@dataclass(frozen=True, kw_only=True)
class FinetuneParams(PpoParams):
    """PpoParams (robot_rl/config/ppo.yaml's keys) and the student to start from; see
    robot_rl/config/ppo_finetune.yaml."""

    student: str = param(doc="the bc_dagger run or shipped policy folder whose student.npz the actor starts "
                             "as: absolute, or relative to hopper_training's package (e.g. policies/end_to_end)")
    log_std_init: float = param(low=-20.0, high=2.0, doc="gSDE's log standard deviation at the start (per "
                                                         "feature of the last hidden layer and joint)")
    sde_sample_freq: int = param(low=1, high=1_000_000, doc="env steps between two draws of gSDE's noise")
    target_kl: float = param(low=0.0, low_open=True, doc="an update stops its epochs once the approximate KL "
                                                         "from the rollout's policy passes 1.5 x this")
    frozen_policy_updates: int = param(low=0, high=1_000_000, doc="updates at the start in which only the "
                                                                  "critic learns (the actor held)")

    def check(self, source: str) -> None:
        super().check(source)
        if self.normalise_observations:
            raise ParamError(f"{source}: ppo_finetune normalises the observations by its student's fixed statistics: "
                             f"normalise_observations must be false")

    def algorithm(self) -> Callable[..., BaseAlgorithm]:
        return FinetunePPO

    def algorithm_kwargs(self) -> dict[str, Any]:
        values = super().algorithm_kwargs()
        for key in ("student", "log_std_init", "frozen_policy_updates"):
            del values[key]
        return {**values, "use_sde": True}

    def check_action_space(self, space: gymnasium.spaces.Space[Any], source: str) -> None:
        if not isinstance(space, gymnasium.spaces.Box):
            raise ParamError(f"{source}: ppo_finetune fine-tunes a student of Box actions, the task has {space}")

    def policy_kwargs(self, network: list[int]) -> dict[str, Any]:
        return {"net_arch": {"pi": network, "vf": network}, "activation_fn": torch.nn.Tanh, "squash_output": True,
                "log_std_init": self.log_std_init, "features_extractor_class": Normalise}


def student_folder(params: FinetuneParams) -> Path:
    """The folder `params.student` names: absolute, or relative to hopper_training's package (the students' home)."""
    folder = Path(params.student).expanduser()
    return folder if folder.is_absolute() else package_path("hopper_training") / folder


def load_student(folder: Path) -> NumpyStudent:
    """The student in `folder` (student.npz, its sha256 checked against the folder's agent.json where it has one)."""
    digest = None
    checkpoint = folder / DEEP_CHECKPOINT  # a bc_dagger run's or shipped policy's agent.json, naming the sha256
    if checkpoint.is_file():
        try:
            digest = json.loads(checkpoint.read_text(encoding="utf-8")).get("weights_sha256")
        except (OSError, ValueError, AttributeError) as error:
            raise RunFileError(f"{checkpoint}: not a checkpoint ({error})") from None
    return NumpyStudent.load(folder, digest)


def check_fit(action_space: gymnasium.spaces.Space[Any], observation_space: gymnasium.spaces.Space[Any], n_envs: int,
              agent_params: Any, source: str) -> None:
    """The agent registry's fit check, before a run folder is made (ParamError in one line): Box actions, a rollout
    buffer that fits the memory, and a student that loads and fits these params and the task's observation."""
    assert isinstance(agent_params, FinetuneParams)
    agent_params.check_action_space(action_space, source)
    size = int(np.prod(observation_space.shape or (1,)))
    try:
        agent_params.check_memory(size, n_envs)
        student = load_student(student_folder(agent_params))
    except (ValueError, RunFileError) as error:
        raise ParamError(f"{source}: {error}") from None
    layers = [w.shape for w, _ in student.layers]
    network = [agent_params.hidden_units] * agent_params.hidden_layers
    if student.mean.shape != (size,) or [n for n, _ in layers[:-1]] != network:
        raise ParamError(f"{source}: the student {agent_params.student!r} (layers {layers}, {student.mean.shape[0]} "
                         f"inputs) does not fit hidden_layers {agent_params.hidden_layers} x hidden_units "
                         f"{agent_params.hidden_units} and this task's {size} observations")


def start_from_student(model: FinetunePPO, student: NumpyStudent, source: str) -> None:
    """Make `model`'s actor the student: the normaliser, the hidden layers and the action layer (pre-tanh)."""
    policy, normalise = model.policy, model.policy.features_extractor
    assert isinstance(policy, ActorCriticPolicy) and isinstance(normalise, Normalise)
    hidden = [m for m in policy.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
    assert isinstance(policy.action_net, torch.nn.Linear)
    linears = [*hidden, policy.action_net]
    shapes = [tuple(layer.weight.shape) for layer in linears]
    if shapes != [w.shape for w, _ in student.layers] or normalise.mean.shape != student.mean.shape:
        raise ParamError(f"{source}: the student's layers {[w.shape for w, _ in student.layers]} (inputs "
                         f"{student.mean.shape[0]}) do not fit the actor's {shapes} (observation "
                         f"{normalise.mean.shape[0]}): hidden_layers/hidden_units must be the "
                         f"student's, the task the one it learned")
    with torch.no_grad():
        normalise.mean.copy_(torch.as_tensor(student.mean))
        normalise.std.copy_(torch.as_tensor(student.std))
        for layer, (weights, bias) in zip(linears, student.layers):
            layer.weight.copy_(torch.as_tensor(weights))
            layer.bias.copy_(torch.as_tensor(bias))


def make_trainer(agent: Any, env: Any, task: Any, params: Any, run: Any, hooks: Any, resume: bool,
                 agent_params: Any, max_steps: int | None, agent_config: Path | None) -> DeepTrainer:
    """The agent registry's entry: robot_rl's DeepTrainer on FinetunePPO, its actor the student unless resuming
    (a resume takes every weight from the run's model.zip)."""
    assert isinstance(agent_params, FinetuneParams)
    source = f"agent {agent.name}'s student {agent_params.student!r}"
    student = None if resume else load_student(student_folder(agent_params))
    trainer = DeepTrainer(env, task, params, agent, agent_params, run, hooks, resume, max_steps, agent_config)
    assert isinstance(trainer.model, FinetunePPO)
    trainer.model.frozen_policy_steps = agent_params.frozen_policy_updates * agent_params.n_steps * trainer.n_envs
    if student is not None:
        start_from_student(trainer.model, student, source)
    return trainer
