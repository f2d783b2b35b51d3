"""Deep agents' training: Stable-Baselines3's DQN, PPO and SAC on any task, over ROS or direct, with one env or N.

Needs requirements-deep.txt (torch, stable-baselines3), which ./ws installs the first time a deep agent
is asked for. Agents run on the CPU with one torch thread (the envs' workers need the other core).
The params of each agent are robot_rl.agents.sb3.params', its N envs robot_rl.agents.sb3.vec_env's.

- `ScaledRewards`: the rewards the agent learns from, times `reward_scale`; the run's returns stay the task's.
- `DeepTrainer`: trains until `nepisodes` episodes have ended (or `max_steps` env steps: then DQN's
  exploration falls over a share of those steps, SB3's way; without it over a share of the episodes,
  like tabular Q-learning's epsilon, by `EpisodeSchedule`); its RunLedger writes the run as tabular
  Q-learning's does (episodes.csv with the task's metrics, learning_curve.png, summary.json), the
  checkpoint being SB3's model.zip and our agent.json (JSON: the agent's params and the counters).
- Resume rebuilds the model from the run's params (params.yaml, agent.json) and loads only the weights
  from model.zip (SB3's set_parameters: torch tensors read with weights_only; SB3's pickled `data` is
  never unpickled) before any file of the run changes: model.zip must have the sha256 agent.json
  recorded when it was written and fit the rebuilt model, else one line naming model.zip (a
  RunFileError). The counters (episodes, env steps, SB3's num_timesteps, so DQN's exploration
  schedule goes on where it was) come from agent.json. Not saved: DQN's and SAC's replay buffers (SB3
  pickles them) and the optimiser's RNG streams, so a resumed DQN or SAC first collects
  `learning_starts` new transitions with its current policy before it trains again, and a resumed run
  is not bit-for-bit the uninterrupted one; PPO's rollout under way at the checkpoint is collected anew.
- `make_trainer` is the agent registry's entry point (robot_rl.agents.registry).
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import torch
from stable_baselines3 import DQN
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from ...envs.base import assist_setter
from ...params import Params, TaskParams
from ...runs.ledger import (
    DEFAULT_HOOKS,
    Learner,
    RunLedger,
    TrainingHooks,
    TrainingState,
    format_duration,
    restored_state,
)
from ...runs.results import EpisodeRecord, RunDirectory, RunFileError, aggregate
from ...task import Episode, TaskSpec, episode_duration
from ..registry import AgentSpec
from .normaliser import NormaliserUpdates, RunningNormaliser
from .params import DqnParams, NetworkParams

CHECKPOINT_FORMAT = "robot_rl.deep_checkpoint/1"  # a format name written in agent.json: kept as it was
PARTIAL_MODEL = "model.partial.zip"  # model.zip being written


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def one_line_reason(error: BaseException) -> str:
    """An error of zipfile, torch or SB3 in one short line; torch's advice to load with weights_only=False (which
    would run whatever the file holds) is left out."""
    text = " ".join(str(error).split())
    if "weights_only" in text:
        return "it holds more than torch tensors (refused: loading it could run code)"
    return f"{type(error).__name__}: {text[:200]}{'...' if len(text) > 200 else ''}"


def build_model(agent_params: NetworkParams, env: VecEnv | gymnasium.Env[Any, Any], gamma: float,
                seed: int) -> BaseAlgorithm:
    """The SB3 model these params are for, on the CPU, with a logger that writes nothing (SB3's default one
    makes an empty folder /tmp/SB3-<date> at every learn())."""
    network = [agent_params.hidden_units] * agent_params.hidden_layers
    model = agent_params.algorithm()("MlpPolicy", env, gamma=gamma, seed=seed, device="cpu", verbose=0,
                                     policy_kwargs=agent_params.policy_kwargs(network),
                                     **agent_params.algorithm_kwargs())
    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


class EpisodeSchedule:
    """DQN's exploration rate by the share of the episodes done (`progress`, set by the trainer): from
    `initial` down to `final` over the first `fraction` of them, then `final`. Used when the budget is
    nepisodes, not a number of env steps (SB3's own schedule is by steps). Picklable, as SB3 saves it."""

    def __init__(self, initial: float, final: float, fraction: float):
        self.initial, self.final, self.fraction = initial, final, fraction
        self.progress = 0.0

    def __call__(self, _progress_remaining: float) -> float:
        if self.fraction <= 0.0 or self.progress >= self.fraction:
            return self.final
        return self.initial + (self.final - self.initial) * self.progress / self.fraction


class ScaledRewards(VecEnvWrapper):
    """The rewards of `venv` times `scale`, as the agent learns from them (the network's targets then have the
    size its learning rate suits: a return of 5000 is 5 at scale 0.001)."""

    def __init__(self, venv: VecEnv, scale: float):
        super().__init__(venv)
        self.scale = scale

    def reset(self) -> VecEnvObs:
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        observations, rewards, dones, infos = self.venv.step_wait()
        return observations, rewards * np.float32(self.scale), dones, infos


class _EpisodeLogger(BaseCallback):
    """Follows each env's episodes in SB3's rollouts and hands every finished one to the trainer."""

    def __init__(self, trainer: DeepTrainer):
        super().__init__()
        self.trainer = trainer

    def _on_training_start(self) -> None:
        n = self.training_env.num_envs
        self.returns, self.steps = [0.0] * n, [0] * n

    def _on_step(self) -> bool:
        rewards, dones, infos = self.locals["rewards"], self.locals["dones"], self.locals["infos"]
        on_step, scale = self.trainer.on_step, self.trainer.agent_params.reward_scale
        for i in range(len(dones)):
            reward = float(rewards[i]) / scale  # the task's reward
            self.returns[i] += reward
            self.steps[i] += 1
            on_step(reward, self.returns[i])
            if dones[i]:
                info = infos[i]
                self.trainer.episode_done(i, self.steps[i], self.returns[i],
                                          not info.get("TimeLimit.truncated", False), info)
                self.returns[i], self.steps[i] = 0.0, 0
        return self.trainer.keep_going()


class DeepTrainer(Learner):
    """Trains the deep `agent` (its params `agent_params`) on `env` (an SB3 VecEnv, or one gymnasium env)
    and writes `run`."""

    def __init__(self, env: VecEnv | gymnasium.Env[Any, Any], task: TaskSpec[Any], params: TaskParams,
                 agent: AgentSpec, agent_params: NetworkParams, run: RunDirectory,
                 hooks: TrainingHooks = DEFAULT_HOOKS, resume: bool = False, max_steps: int | None = None,
                 agent_config: Path | None = None):
        torch.set_num_threads(1)
        self.agent_config = None if agent_config is None else str(agent_config)  # where agent_params came from
        self.env: VecEnv = env if isinstance(env, VecEnv) else DummyVecEnv([lambda: env])
        if agent_params.reward_scale != 1.0:
            self.env = ScaledRewards(self.env, agent_params.reward_scale)
        self.task, self.params, self.agent, self.run = task, params, agent, run
        self.on_step, self.should_stop = hooks.on_step, hooks.should_stop
        self.max_steps = max_steps if max_steps is not None else params.nepisodes * params.nsteps  # at most
        self.step_budget = max_steps or 0  # as given (max_steps:=, 0: none, nepisodes decides): summary.json's
        self.n_envs = self.env.num_envs
        run.checkpoint_name = agent.checkpoint_name
        agent_params.check_action_space(self.env.action_space, f"agent {agent.name} on {task.env_id}")
        agent_params.check_memory(int(np.prod(self.env.observation_space.shape or (1,))), self.env.num_envs)
        self.model = build_model(agent_params, self.env, params.gamma, params.seed)
        self.agent_params = agent_params
        self.schedule: EpisodeSchedule | None = None
        if isinstance(self.model, DQN) and max_steps is None:
            assert isinstance(agent_params, DqnParams)
            self.schedule = EpisodeSchedule(agent_params.exploration_initial_eps, agent_params.exploration_final_eps,
                                            agent_params.exploration_fraction)
            self.model.exploration_schedule = self.schedule
        self.stopped: str | None = None
        self._timesteps_offset = self._steps_at_start = 0
        self._hooks, self._resuming = hooks, ""
        if resume:
            self.state, num_timesteps = run.prepare_resume(self._restore)
            self.model.num_timesteps = num_timesteps
            if isinstance(self.model, OffPolicyAlgorithm):  # replay buffer not saved: fill it anew first
                self.model.learning_starts = num_timesteps + self.model.learning_starts
            self._resuming = (f"Resuming {run.path} after episode {self.state.episode} "
                              f"({self.state.env_steps} env steps)")
        else:
            self.state = TrainingState()
        if self.schedule is not None:
            self.schedule.progress = self.state.episode / params.nepisodes
        self.ledger = RunLedger(run, task, params.nepisodes, self.state, self, hooks, n_envs=self.n_envs,
                                count_env_steps=self._count_steps, max_steps=max_steps,
                                assist=params.attitude_assist,
                                set_assist=assist_setter(env))

    def _restore(self, checkpoint: dict[str, Any]) -> tuple[TrainingState, int]:
        """The counters of a checkpoint, checked against this run (ValueError/KeyError/TypeError if not)."""
        state = restored_state(checkpoint, CHECKPOINT_FORMAT, self.task)
        if checkpoint["agent"] != self.agent.name:
            raise ValueError(f"it is of agent {checkpoint['agent']!r}, this run trains {self.agent.name!r}")
        # its params with today's defaults (a checkpoint from before reward_scale has none)
        self.agent_params.require_saved(checkpoint["agent_params"])
        num_timesteps = checkpoint["num_timesteps"]
        if not (isinstance(num_timesteps, int) and num_timesteps >= 0):
            raise ValueError(f"num_timesteps {num_timesteps!r} is not a count")
        self._load_weights(checkpoint.get("model_sha256"))
        return state, num_timesteps

    def _load_weights(self, digest: Any) -> None:
        """The weights of model.zip into the rebuilt model, if it is the file agent.json recorded (`digest`;
        None in a checkpoint written before digests were) and fits the model; else RunFileError. A checkpoint
        cut short after agent.json but before its model.partial.zip became model.zip is completed first."""
        model_zip, partial = self.run.model_zip, self.run.path / PARTIAL_MODEL
        if digest is not None and not isinstance(digest, str):
            raise ValueError(f"model_sha256 {digest!r} is not a digest")
        if digest is not None and partial.is_file() and _sha256(partial) == digest:
            partial.replace(model_zip)  # the checkpoint agent.json describes, written whole
        if not model_zip.is_file():
            raise RunFileError(f"{model_zip}: missing: the checkpoint {self.run.checkpoint_json} needs it")
        if digest is not None and _sha256(model_zip) != digest:
            raise RunFileError(f"{model_zip}: not the model.zip this run's checkpoint recorded (its sha256 differs "
                               f"from {self.run.checkpoint_json}'s): damaged, cut short, or another run's")
        try:
            self.model.set_parameters(str(model_zip), exact_match=True, device="cpu")
        except Exception as error:  # noqa: BLE001 (zipfile, torch and SB3 each raise their own)
            raise RunFileError(f"{model_zip}: not weights of this run's {self.agent.name} model: "
                               f"{one_line_reason(error)}") from None

    def save_checkpoint(self) -> None:
        """model.partial.zip (SB3's format), agent.json (ours, with that file's sha256), then model.partial.zip
        renamed model.zip: a resume finds agent.json with its model.zip, or completes the rename. A write that
        fails leaves no partial file."""
        partial = self.run.path / PARTIAL_MODEL
        try:
            self.model.save(str(partial))
            self.run.checkpoint({"format": CHECKPOINT_FORMAT, "task": self.task.env_id, "agent": self.agent.name,
                                 "agent_params": self.agent_params.to_mapping(), "agent_config": self.agent_config,
                                 "envs": self.n_envs,
                                 "episode": self.state.episode, "num_timesteps": int(self.model.num_timesteps),
                                 "model_sha256": _sha256(partial), "state": dataclasses.asdict(self.state)})
        except BaseException:
            partial.unlink(missing_ok=True)
            raise
        partial.replace(self.run.model_zip)

    def _exploration(self) -> float:
        """The epsilon column: DQN's exploration rate (PPO explores by sampling its policy: NaN)."""
        return float(self.model.exploration_rate) if isinstance(self.model, DQN) else math.nan

    def episode_label(self, epsilon: float) -> str:
        return f"{self.agent.name}: exploration {epsilon:.2f}" if isinstance(self.model, DQN) else self.agent.name

    def exploration_label(self) -> str:
        return f", exploration {self._exploration():.3f}" if isinstance(self.model, DQN) else ""

    def summary_fields(self) -> dict[str, Any]:
        return {"agent": self.agent.name, "agent_config": self.agent_config, "envs": self.n_envs,
                "max_steps": self.step_budget}

    def closing_lines(self, summary: dict[str, Any], last: Sequence[EpisodeRecord]) -> list[str]:
        state, metric = self.state, self.task.headline_metric
        headline = aggregate({metric: [r.metrics[metric] for r in last]})
        return [f"{self.agent.name}: {state.episode} episodes, {state.env_steps} env steps in "
                f"{format_duration(state.wall_time)}; over the last {len(last)} episodes: "
                f"{', '.join(f'{k} {v:.3g}' for k, v in headline.items() if v is not None)}"]

    def episode_done(self, env_index: int, steps: int, return_: float, terminated: bool, info: dict[str, Any]) -> None:
        """Hand one finished episode of env `env_index` to the ledger."""
        if self.state.episode >= self.params.nepisodes:
            return  # an episode of another env that ended after the last one counted
        if self.schedule is not None:
            self.schedule.progress = (self.state.episode + 1) / self.params.nepisodes
        episode = Episode(steps=steps, return_=return_, terminated=terminated,
                          duration=episode_duration(info, steps, self.params.running_step), info=info)
        self.ledger.episode_done(episode, return_, self._exploration(), env_index)

    def _count_steps(self) -> int:
        return int(self.model.num_timesteps) - self._timesteps_offset + self._steps_at_start

    def keep_going(self) -> bool:
        """Whether SB3 should take another step (and a progress line every progress_every_s)."""
        self.ledger.log_progress_if_due()
        if self.should_stop():
            self.stopped = "interrupted"
            return False
        return self.state.episode < self.params.nepisodes

    def _callbacks(self) -> list[BaseCallback]:
        """SB3's callbacks of a learn(): the episodes to the ledger, and the observations to a normaliser if any."""
        callbacks: list[BaseCallback] = [_EpisodeLogger(self)]
        if isinstance(getattr(self.model.policy, "features_extractor", None), RunningNormaliser):
            callbacks.append(NormaliserUpdates())
        return callbacks

    def train(self) -> dict[str, Any]:
        """Train until nepisodes episodes (or max_steps env steps); returns the summary written to summary.json."""
        state, ledger = self.state, self.ledger
        if self._resuming:  # said when training starts: a resume of a complete run trains nothing
            self._hooks.log(self._resuming)
        ledger.start()
        self._timesteps_offset, self._steps_at_start = int(self.model.num_timesteps), state.env_steps
        remaining = self.max_steps - state.env_steps
        if state.episode < self.params.nepisodes and remaining > 0 and not self.should_stop():
            with ledger.saved_on_stop():
                self.model.learn(total_timesteps=remaining, callback=self._callbacks(), reset_num_timesteps=False)
        ledger.sync_env_steps()
        done = state.episode >= self.params.nepisodes or state.env_steps >= self.max_steps
        return ledger.close(done, self.stopped)


def make_trainer(agent: AgentSpec, env: VecEnv | gymnasium.Env[Any, Any], task: TaskSpec[Any], params: TaskParams,
                 run: RunDirectory, hooks: TrainingHooks, resume: bool, agent_params: Params | None,
                 max_steps: int | None, agent_config: Path | None) -> DeepTrainer:
    assert isinstance(agent_params, NetworkParams)
    return DeepTrainer(env, task, params, agent, agent_params, run, hooks, resume, max_steps, agent_config)
