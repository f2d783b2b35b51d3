"""Deep agents: Stable-Baselines3's DQN, PPO and SAC on any task, over ROS or direct, with one env or N.

Needs requirements-deep.txt (torch, stable-baselines3), which ./ws installs the first time a deep agent
is asked for. Agents run on the CPU with one torch thread (the envs' workers need the other core).

- `RobotVecEnv`: a Stable-Baselines3 VecEnv over `robot_rl.vector.EnvWorkers` (one process per env; over
  ROS each with its own master and sim node). SB3's conventions: done = terminated or truncated, the
  last observation in info["terminal_observation"], info["TimeLimit.truncated"], the env reset at once.
  `seed(s)` gives worker i the i-th seed numpy's SeedSequence(s) derives, as the gymnasium face does.
- `DqnParams`, `PpoParams`, `SacParams`: each agent's params (robot_rl/config/<agent>.yaml) and its SB3
  algorithm. DQN needs a task with Discrete actions, SAC one with Box actions, PPO takes either; an action
  travels to the env as the space holds it (an int, or a float32 array). `reward_scale` (every agent's)
  multiplies the rewards the agent learns from (`ScaledRewards`); the run's returns stay the task's.
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
- `make_trainer`, `make_vec_env`, `greedy_policy`: the agent registry's entry points (robot_rl.agents);
  `greedy_policy` is a trained run's deterministic policy, for evaluate.py and the training video.
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium
import numpy as np
import torch
from stable_baselines3 import DQN, PPO, SAC
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from .ledger import DEFAULT_HOOKS, Learner, RunLedger, TrainingHooks, TrainingState, format_duration, restored_state
from .params import MAX_COUNT, ParamError, Params, TaskParams, param
from .results import EpisodeRecord, RunDirectory, RunFileError, aggregate
from .task import Episode, TaskSpec, episode_duration
from .vector import EnvWorkers, as_env_actions, make_env_workers, worker_seeds

if TYPE_CHECKING:
    from .agents import AgentSpec
    from .evaluation import TrainedRun

CHECKPOINT_FORMAT = "robot_rl.deep_checkpoint/1"
PARTIAL_MODEL = "model.partial.zip"  # model.zip being written


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


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _one_line_reason(error: BaseException) -> str:
    """An error of zipfile, torch or SB3 in one short line; torch's advice to load with weights_only=False (which
    would run whatever the file holds) is left out."""
    text = " ".join(str(error).split())
    if "weights_only" in text:
        return "it holds more than torch tensors (refused: loading it could run code)"
    return f"{type(error).__name__}: {text[:200]}{'...' if len(text) > 200 else ''}"


@dataclass(frozen=True, kw_only=True)
class NetworkParams(Params):
    hidden_layers: int = param(low=1, high=8, doc="hidden layers of the MLP")
    hidden_units: int = param(low=1, high=4096, doc="units per hidden layer")
    learning_rate: float = param(low=0.0, low_open=True, high=1.0, doc="Adam's step size")
    reward_scale: float = param(low=0.0, low_open=True, high=1e6, default=1.0,
                                doc="the agent learns from the task's rewards times this (the run's files keep "
                                    "the task's)")

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

    def algorithm(self) -> Callable[..., BaseAlgorithm]:
        return PPO

    def buffer_bytes(self, observation_size: int, n_envs: int) -> int:
        """SB3's rollout buffer (float32): per env step an observation, action, reward, return, advantage, value..."""
        return self.n_steps * n_envs * 4 * (observation_size + 7)

    def policy_kwargs(self, network: list[int]) -> dict[str, Any]:
        return {"net_arch": {"pi": network, "vf": network}}


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


class RobotVecEnv(VecEnv):
    """A Stable-Baselines3 VecEnv over EnvWorkers (see the module docstring)."""

    def __init__(self, workers: EnvWorkers):
        self.workers = workers
        super().__init__(workers.n, workers.observation_space, workers.action_space)

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        self._seeds = list(worker_seeds(seed, self.num_envs))
        return self._seeds

    def reset(self) -> np.ndarray:
        replies = self.workers.request_all("reset", [(s, o or None) for s, o in zip(self._seeds, self._options)])
        self.reset_infos = [info for _, info in replies]
        self._reset_seeds()
        self._reset_options()
        return np.stack([observation for observation, _ in replies])

    def step_async(self, actions: np.ndarray) -> None:
        for i, action in enumerate(as_env_actions(actions, self.action_space, self.num_envs)):
            self.workers.send(i, "step", action)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        replies = self.workers.receive_all(what="answer a step")
        observations, rewards, dones, infos = [], [], [], []
        for i, (observation, reward, terminated, truncated, info, final) in enumerate(replies):
            if final is not None:  # the worker has reset: `info` is the reset's, `final` the episode's last
                self.reset_infos[i] = info
                info = {**final[1], "terminal_observation": final[0]}
            info["TimeLimit.truncated"] = truncated and not terminated
            observations.append(observation)
            rewards.append(reward)
            dones.append(terminated or truncated)
            infos.append(info)
        return (np.stack(observations), np.array(rewards, dtype=np.float32), np.array(dones, dtype=np.bool_),
                infos)

    def close(self) -> None:
        self.workers.close()

    def _indices(self, indices: Any) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        return [indices] if isinstance(indices, int) else list(indices)

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        targets = self._indices(indices)
        for i in targets:
            self.workers.send(i, "get_attr", attr_name)
        return [self.workers.receive(i, what=f"answer get_attr {attr_name!r}") for i in targets]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        targets = self._indices(indices)
        for i in targets:
            self.workers.send(i, "call", ("__setattr__", (attr_name, value), {}))
        for i in targets:
            self.workers.receive(i, what=f"answer set_attr {attr_name!r}")

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any) -> list[Any]:
        targets = self._indices(indices)
        for i in targets:
            self.workers.send(i, "call", (method_name, method_args, method_kwargs))
        return [self.workers.receive(i, what=f"answer {method_name}()") for i in targets]

    def env_is_wrapped(self, wrapper_class: type[gymnasium.Wrapper[Any, Any, Any, Any]],
                       indices: Any = None) -> list[bool]:
        """Only gymnasium's TimeLimit wraps a worker's env (and SB3 never asks about it)."""
        return [wrapper_class is gymnasium.wrappers.TimeLimit for _ in self._indices(indices)]


def make_vec_env(task: TaskSpec[Any], n: int, backend: str, seed: int, params: TaskParams,
                 ros_timeout: float = 10.0, cluster: str | None = None) -> RobotVecEnv:
    """N envs of `task` in worker processes (or Ray actors on `cluster`), as an SB3 VecEnv."""
    return RobotVecEnv(make_env_workers(task, n, cluster, backend=backend, seed=seed, params=params,
                                        ros_timeout=ros_timeout))


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
        if resume:
            self.state, num_timesteps = run.prepare_resume(self._restore)
            self.model.num_timesteps = num_timesteps
            if isinstance(self.model, OffPolicyAlgorithm):  # replay buffer not saved: fill it anew first
                self.model.learning_starts = num_timesteps + self.model.learning_starts
            hooks.log(f"Resuming {run.path} after episode {self.state.episode} ({self.state.env_steps} env steps)")
        else:
            self.state = TrainingState()
        if self.schedule is not None:
            self.schedule.progress = self.state.episode / params.nepisodes
        self.ledger = RunLedger(run, task, params.nepisodes, self.state, self, hooks, n_envs=self.n_envs,
                                count_env_steps=self._count_steps, max_steps=max_steps)

    def _restore(self, checkpoint: dict[str, Any]) -> tuple[TrainingState, int]:
        """The counters of a checkpoint, checked against this run (ValueError/KeyError/TypeError if not)."""
        state = restored_state(checkpoint, CHECKPOINT_FORMAT, self.task)
        if checkpoint["agent"] != self.agent.name:
            raise ValueError(f"it is of agent {checkpoint['agent']!r}, this run trains {self.agent.name!r}")
        try:  # its params with today's defaults (a checkpoint from before reward_scale has none)
            saved = self.agent_params.from_mapping(checkpoint["agent_params"], "agent_params")
        except ParamError as error:
            raise ValueError(str(error)) from None
        if saved != self.agent_params:
            here = self.agent_params.to_mapping()
            differ = ", ".join(f"{key} {value!r} there, {here[key]!r} here"
                               for key, value in saved.to_mapping().items() if value != here[key])
            raise ValueError(f"its agent params differ from this run's ({differ}): resume with the params the run "
                             "began with")
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
                               f"{_one_line_reason(error)}") from None

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
                "max_steps": self.max_steps}

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

    def train(self) -> dict[str, Any]:
        """Train until nepisodes episodes (or max_steps env steps); returns the summary written to summary.json."""
        state, ledger = self.state, self.ledger
        ledger.start()
        self._timesteps_offset, self._steps_at_start = int(self.model.num_timesteps), state.env_steps
        remaining = self.max_steps - state.env_steps
        if state.episode < self.params.nepisodes and remaining > 0 and not self.should_stop():
            with ledger.saved_on_stop():
                self.model.learn(total_timesteps=remaining, callback=_EpisodeLogger(self), reset_num_timesteps=False)
        ledger.sync_env_steps()
        done = state.episode >= self.params.nepisodes or state.env_steps >= self.max_steps
        return ledger.close(done, self.stopped)


class DeepPolicy:
    """A trained run's deterministic policy: observation -> action."""

    def __init__(self, model: BaseAlgorithm):
        self.model = model

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        action, _ = self.model.predict(observation, deterministic=True)
        return as_env_actions(action, self.model.action_space, 1)[0]


def make_trainer(agent: AgentSpec, env: VecEnv | gymnasium.Env[Any, Any], task: TaskSpec[Any], params: TaskParams,
                 run: RunDirectory, hooks: TrainingHooks, resume: bool, agent_params: Params | None,
                 max_steps: int | None, agent_config: Path | None) -> DeepTrainer:
    assert isinstance(agent_params, NetworkParams)
    return DeepTrainer(env, task, params, agent, agent_params, run, hooks, resume, max_steps, agent_config)


def greedy_policy(run: TrainedRun, checkpoint: dict[str, Any]) -> Callable[[gymnasium.Env[Any, Any], int], DeepPolicy]:
    """The greedy policy of a deep run: the model rebuilt from agent.json's params, its weights from model.zip."""
    try:
        if checkpoint.get("format") != CHECKPOINT_FORMAT:
            raise ValueError(f"format {checkpoint.get('format')!r}")
        agent_params = run.agent.load_params_from(checkpoint["agent_params"], str(run.path))
    except (KeyError, TypeError, ValueError, ParamError) as error:
        raise ValueError(f"{run.path}: not a deep agent's checkpoint ({error})") from None
    assert isinstance(agent_params, NetworkParams)

    def policy(env: gymnasium.Env[Any, Any], _seed: int) -> DeepPolicy:
        torch.set_num_threads(1)
        model = build_model(agent_params, DummyVecEnv([lambda: env]), run.params.gamma, run.params.seed)
        model_zip = run.path.with_name("model.zip")
        try:
            model.set_parameters(str(model_zip), exact_match=True, device="cpu")
        except Exception as error:  # noqa: BLE001 (zipfile, torch and SB3 each raise their own)
            raise RunFileError(f"{model_zip}: not weights of this run's model: {_one_line_reason(error)}") from None
        return DeepPolicy(model)
    return policy
