"""Each deep agent's params (robot_rl/config/<agent>.yaml) and the Stable-Baselines3 algorithm they are for.

`DqnParams`, `PpoParams`, `SacParams`: DQN needs a task with Discrete actions, SAC one with Box actions, PPO
takes either. `reward_scale` (every agent's) multiplies the rewards the agent learns from; the run's returns
stay the task's. Another SB3 algorithm needs only its `NetworkParams` subclass here.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np
from stable_baselines3 import DQN, PPO, SAC
from stable_baselines3.common.base_class import BaseAlgorithm

from ...params import MAX_COUNT, DeepAgentParams, ParamError, Params, param
from .normaliser import RunningNormaliser


def _available_memory() -> int | None:
    """MemAvailable of /proc/meminfo in bytes (None where there is none)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


@dataclass(frozen=True, kw_only=True)
class NetworkParams(DeepAgentParams):

    def algorithm(self) -> Callable[..., BaseAlgorithm]:
        """The SB3 algorithm these params are for (DQN, PPO and SAC take gamma, BaseAlgorithm does not)."""
        raise NotImplementedError

    def algorithm_kwargs(self) -> dict[str, Any]:
        """The algorithm's keyword arguments from these params (the network's are policy_kwargs')."""
        values = self.to_mapping()
        for key in ("hidden_layers", "hidden_units", "reward_scale"):
            del values[key]
        return values

    def check_action_space(self, space: gymnasium.spaces.Space[Any], source: str) -> None:
        """ParamError in one line when the algorithm cannot act in `space`."""

    def policy_kwargs(self, network: list[int]) -> dict[str, Any]:
        """SB3's policy_kwargs for hidden layers of these sizes."""
        raise NotImplementedError

    def buffer_bytes(self, observation_size: int, n_envs: int) -> int:
        """The bytes the algorithm's buffer of transitions takes."""
        raise NotImplementedError

    def check_memory(self, observation_size: int, n_envs: int) -> None:
        """ValueError in one line when the buffer would not fit the memory available (SB3 would allocate it and
        die with a MemoryError, or the kernel would end the process)."""
        needed, available = self.buffer_bytes(observation_size, n_envs), _available_memory()
        if available is not None and needed > available:
            raise ValueError(f"the agent's buffer needs {needed / 2**30:.3g} GiB, more than the "
                             f"{available / 2**30:.3g} GiB of memory available: lower buffer_size (DQN, SAC) or "
                             f"n_steps (PPO) in the agent_config")


@dataclass(frozen=True, kw_only=True)
class DqnParams(NetworkParams):
    """Stable-Baselines3 DQN's arguments (gamma is the task's); see robot_rl/config/dqn.yaml."""

    buffer_size: int = param(low=1, high=MAX_COUNT, doc="replay buffer capacity (transitions)")
    learning_starts: int = param(low=0, high=MAX_COUNT, doc="transitions collected before the first gradient step")
    batch_size: int = param(low=1, high=MAX_COUNT, doc="transitions per gradient step")
    train_freq: int = param(low=1, high=MAX_COUNT, doc="env steps (per env) between two trainings")
    gradient_steps: int = param(low=1, high=MAX_COUNT, doc="gradient steps per training")
    target_update_interval: int = param(low=1, high=MAX_COUNT, doc="env steps between two target network updates")
    exploration_fraction: float = param(low=0.0, high=1.0, doc="share of the step budget over which epsilon falls")
    exploration_initial_eps: float = param(low=0.0, high=1.0, doc="epsilon at the start")
    exploration_final_eps: float = param(low=0.0, high=1.0, doc="epsilon at the end of the fall")

    def algorithm(self) -> Callable[..., BaseAlgorithm]:
        return DQN

    def check_action_space(self, space: gymnasium.spaces.Space[Any], source: str) -> None:
        if not isinstance(space, gymnasium.spaces.Discrete):
            raise ParamError(f"{source}: DQN needs Discrete actions, the task has {space} (try agent:=sac or ppo)")

    def buffer_bytes(self, observation_size: int, n_envs: int) -> int:
        """SB3's replay buffer: per transition an observation, the next one (float32), action, reward, done, timeout."""
        return self.buffer_size * (2 * 4 * observation_size + 8 + 4 + 4 + 4)

    def policy_kwargs(self, network: list[int]) -> dict[str, Any]:
        return {"net_arch": network}


@dataclass(frozen=True, kw_only=True)
class PpoParams(NetworkParams):
    """Stable-Baselines3 PPO's arguments (gamma is the task's); see robot_rl/config/ppo.yaml."""

    n_steps: int = param(low=1, high=MAX_COUNT, doc="env steps per env between two updates")
    batch_size: int = param(low=1, high=MAX_COUNT, doc="minibatch size")
    n_epochs: int = param(low=1, high=MAX_COUNT, doc="passes over each rollout")
    gae_lambda: float = param(low=0.0, high=1.0, doc="GAE lambda")
    clip_range: float = param(low=0.0, low_open=True, doc="PPO's clip range")
    ent_coef: float = param(low=0.0, doc="entropy bonus weight")
    normalise_observations: bool = param(default=False, doc="normalise each observation value by its running mean "
                                                            "and variance, inside the network (agents/sb3/normaliser)")

    def algorithm(self) -> Callable[..., BaseAlgorithm]:
        return PPO

    def algorithm_kwargs(self) -> dict[str, Any]:
        values = super().algorithm_kwargs()
        del values["normalise_observations"]
        return values

    def buffer_bytes(self, observation_size: int, n_envs: int) -> int:
        """SB3's rollout buffer (float32): per env step an observation, action, reward, return, advantage, value..."""
        return self.n_steps * n_envs * 4 * (observation_size + 7)

    def policy_kwargs(self, network: list[int]) -> dict[str, Any]:
        kwargs: dict[str, Any] = {"net_arch": {"pi": network, "vf": network}}
        if self.normalise_observations:
            kwargs["features_extractor_class"] = RunningNormaliser
        return kwargs


@dataclass(frozen=True, kw_only=True)
class SacParams(NetworkParams):
    """Stable-Baselines3 SAC's arguments (gamma is the task's); see robot_rl/config/sac.yaml."""

    buffer_size: int = param(low=1, high=MAX_COUNT, doc="replay buffer capacity (transitions)")
    learning_starts: int = param(low=0, high=MAX_COUNT, doc="transitions collected before the first gradient step")
    batch_size: int = param(low=1, high=MAX_COUNT, doc="transitions per gradient step")
    tau: float = param(low=0.0, low_open=True, high=1.0, doc="soft update coefficient of the target networks")
    train_freq: int = param(low=1, high=MAX_COUNT, doc="env steps (per env) between two trainings")
    gradient_steps: int = param(low=1, high=MAX_COUNT, doc="gradient steps per training")
    ent_coef: float = param(low=0.0, low_open=True, doc="entropy coefficient (its start value if learned)")
    learn_ent_coef: bool = param(doc="learn the entropy coefficient towards a target entropy (SB3's 'auto')")

    def algorithm(self) -> Callable[..., BaseAlgorithm]:
        return SAC

    def algorithm_kwargs(self) -> dict[str, Any]:
        values = super().algorithm_kwargs()
        learn = values.pop("learn_ent_coef")
        values["ent_coef"] = f"auto_{values['ent_coef']}" if learn else values["ent_coef"]
        return values

    def check_action_space(self, space: gymnasium.spaces.Space[Any], source: str) -> None:
        if not isinstance(space, gymnasium.spaces.Box):
            raise ParamError(f"{source}: SAC needs Box (continuous) actions, the task has {space} "
                             f"(try agent:=dqn or ppo, or a task with continuous actions)")

    def buffer_bytes(self, observation_size: int, n_envs: int) -> int:
        """SB3's replay buffer: per transition an observation, the next one, an action of at most 8 floats
        (float32), reward, done, timeout."""
        return self.buffer_size * (2 * 4 * observation_size + 4 * 8 + 4 + 4 + 4)

    def policy_kwargs(self, network: list[int]) -> dict[str, Any]:
        return {"net_arch": network}


def check_fit(action_space: gymnasium.spaces.Space[Any], observation_space: gymnasium.spaces.Space[Any], n_envs: int,
              agent_params: Params | None, source: str) -> None:
    """The agent registry's fit check of a deep agent: its algorithm acts in `action_space`, and its buffer fits the
    memory available (ParamError in one line)."""
    assert isinstance(agent_params, NetworkParams)
    agent_params.check_action_space(action_space, source)
    try:
        agent_params.check_memory(int(np.prod(observation_space.shape or (1,))), n_envs)
    except ValueError as error:
        raise ParamError(f"{source}: {error}") from None
