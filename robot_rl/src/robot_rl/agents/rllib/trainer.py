"""Agent rllib_ppo's training: RLlib's PPO (new API stack) with N env runners on Ray and the learner here.

`RllibPpoTrainer` builds RLlib's PPO from the agent's params (robot_rl.agents.rllib.params.ppo_config) on the
runners of an `RllibEnvs` (robot_rl.agents.rllib.runners): each runner holds one env and a copy of the policy
and returns a fragment of rollout_fragment_length env steps per call; the learner (num_learners=0) trains on
the driver, one torch thread. After every update the episodes the runners ended are taken, ordered (by runner,
each runner's as they ended) and handed to the run's RunLedger: episodes.csv (every episode once), the EP: and
progress lines, summary.json, learning_curve.png, and runners.csv (which runner, on which node, ran each
episode). Training stops after the update in which the nepisodes-th episode ended (episodes of that update
beyond it are not written), at max_steps env steps, or when asked to stop (SIGTERM, Ctrl-C): within half a second
(STOP_POLL_S), the update under way abandoned (it runs in a thread of its own; the checkpoint keeps the weights and
episodes of the last finished update, and the runners are ended, not waited for).

The checkpoint is weights only: the RLModule's state as numpy arrays (robot_rl.agents.rllib.policy:
rllib_module.npz, written first as rllib_module.partial.npz), agent.json (its sha256, the params, the
counters), then the rename: a resume finds agent.json with its weights, or completes the rename. No pickle is
written or read. `resume:=true` rebuilds the algorithm from the run's params, loads the weights into the learner
and the runners, and continues the counters (episodes, env steps, updates). Not restored: Adam's moments and
RLlib's own counters and RNG streams (the resumed run is not bit for bit the uninterrupted one), and a
fragment under way at the checkpoint is sampled anew.
"""
from __future__ import annotations

import csv
import dataclasses
import math
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ...atomic import write_text_atomic
from ...envs.backends.factory import over_ros
from ...params import ParamError, Params, TaskParams
from ...runs.ledger import DEFAULT_HOOKS, RunLedger, TrainingHooks, TrainingState, format_duration, restored_state
from ...runs.results import EpisodeRecord, RunDirectory, RunFileError, aggregate
from ...task import Episode, TaskSpec
from ...workers.base import WorkerError
from ..registry import AgentSpec
from .params import RllibPpoParams, ppo_config
from .policy import (
    CHECKPOINT_FORMAT,
    PARTIAL_WEIGHTS,
    WEIGHTS_DIGEST,
    WEIGHTS_FILE,
    load_weights,
    save_weights,
    sha256_of,
)
from .runners import EndedEpisode, RllibEnvs

RUNNERS_CSV = "runners.csv"
RUNNERS_COLUMNS = ("episode", "runner", "node", "node_id")
MODULE = "default_policy"  # RLlib's DEFAULT_MODULE_ID
STOP_POLL_S = 0.5  # s between two looks at the stop request while an update runs


def sampled_count(value: float) -> int:
    """An update's count of sampled env steps as RLlib reports it; 0 when it is NaN, as RLlib reports it when a
    runner's node was lost during the update (its metrics reduced over no values)."""
    return int(value) if math.isfinite(value) else 0


class RllibPpoTrainer:
    """Trains agent rllib_ppo on `envs` and writes `run` (see the module docstring)."""

    def __init__(self, envs: RllibEnvs, task: TaskSpec[Any], params: TaskParams, agent: AgentSpec,
                 agent_params: RllibPpoParams, run: RunDirectory, hooks: TrainingHooks = DEFAULT_HOOKS,
                 resume: bool = False, max_steps: int | None = None, agent_config: Path | None = None):
        import torch
        torch.set_num_threads(1)
        source = f"agent {agent.name} on {task.env_id}"
        try:  # the registry's fit check asked the same before the run folder was made, but for the backend
            agent_params.check_action_space(envs.single_action_space, source)
            agent_params.check_envs(envs.num_envs, over_ros(envs.backend), source)
            agent_params.check_batch(envs.num_envs, source)
        except ParamError as error:
            raise ValueError(str(error)) from None  # the training node's one line
        self.envs, self.task, self.params, self.agent, self.p, self.run = envs, task, params, agent, agent_params, run
        self.agent_config = None if agent_config is None else str(agent_config)
        self.log, self.should_stop, self._hooks = hooks.log, hooks.should_stop, hooks
        self.max_steps = max_steps if max_steps is not None else params.nepisodes * params.nsteps
        self.step_budget = max_steps or 0
        self.stopped: str | None = None
        self.env_steps = self.updates = 0
        self._finished_weights: dict[str, Any] | None = None  # the last finished update's, once one was abandoned
        run.checkpoint_name = agent.checkpoint_name
        config = ppo_config(agent_params, envs.register(),
                            envs.env_config(agent_params.reward_scale, agent_params.envs_per_runner),
                            envs.single_observation_space, envs.single_action_space, envs.num_envs, params.gamma,
                            params.seed)
        try:
            self.algorithm = config.build_algo()
        except Exception as error:  # noqa: BLE001 (RLlib raises Ray's errors, or the env's from a runner)
            text = " ".join(str(error).split())
            raise WorkerError(f"RLlib could not start its {agent_params.runners(envs.num_envs)} env runners: "
                              f"{type(error).__name__}: "
                              f"{text[:400]}{'...' if len(text) > 400 else ''}") from None
        envs.attach(self.algorithm)
        for runner, node, pid in envs.runner_info():
            self.log(f"env runner {runner}/{agent_params.runners(envs.num_envs)}: pid {pid} on node {node}"
                     f"{f', {agent_params.envs_per_runner} envs' if agent_params.envs_per_runner > 1 else ''}")
        self._resuming = ""
        if resume:
            self.state = run.prepare_resume(self._restore)
            self._keep_runner_rows(self.state.episode)
            self._resuming = (f"Resuming {run.path} after episode {self.state.episode} "
                              f"({self.state.env_steps} env steps)")
        else:
            self.state = TrainingState()
            write_text_atomic(self.runners_csv, ",".join(RUNNERS_COLUMNS) + "\n")
        self.ledger = RunLedger(run, task, params.nepisodes, self.state, self, hooks, n_envs=envs.num_envs,
                                count_env_steps=lambda: self.env_steps, max_steps=max_steps,
                                assist=params.attitude_assist)  # its runners' envs: the assist stays

    @property
    def runners_csv(self) -> Path:
        return self.run.path / RUNNERS_CSV

    # -- weights --
    def weights(self) -> dict[str, Any]:
        """The learner's RLModule state: numpy arrays by their state-dict names."""
        state = self.algorithm.learner_group.get_weights([MODULE])[MODULE]
        return {name: value.detach().cpu().numpy() if hasattr(value, "detach") else value
                for name, value in state.items()}

    def set_weights(self, arrays: dict[str, Any]) -> None:
        """`arrays` into the learner's RLModule, then into every runner's copy."""
        import torch
        here = self.weights()
        if set(arrays) != set(here) or any(arrays[k].shape != here[k].shape for k in here):
            raise RunFileError(f"{self.run.path / WEIGHTS_FILE}: not weights of this run's network (its arrays do not "
                               f"match the module's names and shapes)")
        self.algorithm.learner_group.set_weights({MODULE: {k: torch.as_tensor(v) for k, v in arrays.items()}})
        self.algorithm.env_runner_group.sync_weights(from_worker_or_learner_group=self.algorithm.learner_group,
                                                     inference_only=True, timeout_seconds=self.p.sample_timeout_s)

    def _restore(self, checkpoint: dict[str, Any]) -> TrainingState:
        """The counters of a checkpoint, checked against this run, and its weights loaded."""
        state = restored_state(checkpoint, CHECKPOINT_FORMAT, self.task)
        if checkpoint["agent"] != self.agent.name:
            raise ValueError(f"it is of agent {checkpoint['agent']!r}, this run trains {self.agent.name!r}")
        self.p.require_saved(checkpoint["agent_params"])
        if checkpoint["envs"] != self.envs.num_envs:
            raise ValueError(f"it trained with envs:={checkpoint['envs']}, this run has {self.envs.num_envs}: the "
                             f"train batch would differ")
        self.env_steps, self.updates = int(checkpoint["env_steps"]), int(checkpoint["updates"])
        digest, partial, final = checkpoint.get(WEIGHTS_DIGEST), self.run.path / PARTIAL_WEIGHTS, \
            self.run.path / WEIGHTS_FILE
        if isinstance(digest, str) and partial.is_file() and sha256_of(partial) == digest:
            partial.replace(final)  # the checkpoint agent.json describes, written whole
        self.set_weights(load_weights(final, digest, self.run.checkpoint_json))
        return state

    # -- the Learner's side (RunLedger) --
    def save_checkpoint(self) -> None:
        partial = self.run.path / PARTIAL_WEIGHTS
        try:
            weights = self.weights() if self._finished_weights is None else self._finished_weights
            digest = save_weights(partial, weights)
            self.run.checkpoint({"format": CHECKPOINT_FORMAT, "task": self.task.env_id, "agent": self.agent.name,
                                 "agent_params": self.p.to_mapping(), "agent_config": self.agent_config,
                                 "envs": self.envs.num_envs, "episode": self.state.episode,
                                 "env_steps": self.env_steps, "updates": self.updates, WEIGHTS_DIGEST: digest,
                                 "state": dataclasses.asdict(self.state)})
        except BaseException:
            partial.unlink(missing_ok=True)
            raise
        partial.replace(self.run.path / WEIGHTS_FILE)

    def episode_label(self, epsilon: float) -> str:
        return self.agent.name

    def exploration_label(self) -> str:
        return ""

    def summary_fields(self) -> dict[str, Any]:
        return {"agent": self.agent.name, "agent_config": self.agent_config, "envs": self.envs.num_envs,
                "max_steps": self.step_budget, "updates": self.updates}

    def closing_lines(self, summary: dict[str, Any], last: Sequence[EpisodeRecord]) -> list[str]:
        metric = self.task.headline_metric
        headline = aggregate({metric: [r.metrics[metric] for r in last]})
        return [f"{self.agent.name}: {self.state.episode} episodes, {self.env_steps} env steps, {self.updates} "
                f"updates in {format_duration(self.state.wall_time)}; over the last {len(last)} episodes: "
                f"{', '.join(f'{k} {v:.3g}' for k, v in headline.items() if v is not None)}"]

    # -- training --
    def _keep_runner_rows(self, episodes: int) -> None:
        """runners.csv cut back to the checkpoint's episodes (as prepare_resume cuts episodes.csv)."""
        try:
            with open(self.runners_csv, encoding="utf-8", newline="") as f:
                rows = [row for row in csv.reader(f)][1:]
        except FileNotFoundError:
            rows = []
        kept = [row for row in rows if len(row) == len(RUNNERS_COLUMNS) and row[0].isdigit()
                and int(row[0]) <= episodes]
        write_text_atomic(self.runners_csv, "\n".join(",".join(r) for r in [list(RUNNERS_COLUMNS), *kept]) + "\n")

    def _episode_done(self, ended: EndedEpisode) -> None:
        episode = Episode(steps=ended.steps, return_=ended.return_, terminated=ended.terminated,
                          duration=ended.duration, info=ended.info)
        with open(self.runners_csv, "a", encoding="utf-8", newline="") as f:
            row = [self.state.episode + 1, ended.runner, ended.node, ended.node_id]
            csv.writer(f, lineterminator="\n").writerow(row)
        self.ledger.episode_done(episode, ended.return_, math.nan, ended.env)

    def _done(self) -> bool:
        return self.state.episode >= self.params.nepisodes or self.env_steps >= self.max_steps

    def train(self) -> dict[str, Any]:
        """Train until nepisodes episodes (or max_steps env steps); returns the summary written to summary.json."""
        from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED
        if self._resuming:
            self.log(self._resuming)
        self.ledger.start()
        with self.ledger.saved_on_stop():
            while not self._done():
                if self.should_stop():
                    self.stopped = "interrupted"
                    break
                before = self.weights()
                result = self._update()
                if result is None:  # asked to stop during the update: it is abandoned
                    self._finished_weights, self.stopped = before, "interrupted"
                    break
                self.updates += 1
                self.env_steps += sampled_count(result.get(ENV_RUNNER_RESULTS, {}).get(NUM_ENV_STEPS_SAMPLED, 0))
                for ended in self.envs.take_episodes():
                    if self.state.episode >= self.params.nepisodes:
                        break  # ended in the update after the last one counted
                    self._episode_done(ended)
                self.ledger.log_progress_if_due()
        return self.ledger.close(self._done(), self.stopped)

    def _update(self) -> dict[str, Any] | None:
        """One algorithm.train() in a thread of its own; None if a stop was asked for before it finished (the envs
        are then told to end their runners rather than wait for them)."""
        outcome: dict[str, Any] = {}

        def update() -> None:
            try:
                outcome["result"] = self.algorithm.train()
            except BaseException as error:  # noqa: BLE001 (handed to the main thread, or dropped if abandoned)
                outcome["error"] = error
        thread = threading.Thread(target=update, name="rllib-update", daemon=True)
        thread.start()
        while thread.is_alive():
            thread.join(STOP_POLL_S)
            if thread.is_alive() and self.should_stop():
                self.envs.abandon()
                return None
        if "error" in outcome:
            raise outcome["error"]
        return outcome["result"]


def make_trainer(agent: AgentSpec, envs: Any, task: TaskSpec[Any], params: TaskParams, run: RunDirectory,
                 hooks: TrainingHooks, resume: bool, agent_params: Params | None, max_steps: int | None,
                 agent_config: Path | None) -> RllibPpoTrainer:
    """The agent registry's entry point of agent rllib_ppo (its envs: robot_rl.agents.rllib.runners.RllibEnvs)."""
    if not isinstance(envs, RllibEnvs):
        raise ValueError("agent rllib_ppo trains on its own env runners (robot_rl.agents.rllib.runners.RllibEnvs), "
                         "not on an env made for another agent")
    if not isinstance(agent_params, RllibPpoParams):
        raise ValueError(f"agent rllib_ppo needs RllibPpoParams, got {type(agent_params).__name__}")
    return RllibPpoTrainer(envs, task, params, agent, agent_params, run, hooks, resume, max_steps, agent_config)
