"""A training run's bookkeeping, the same for every trainer (tabular, vector tabular, deep).

A trainer keeps its learning loop and hands each finished episode to its `RunLedger`, which counts it
(`TrainingState`), appends its episodes.csv row with the task's metrics, logs its "EP:" line, writes a
checkpoint every `checkpoint_every` episodes, logs a progress line every `progress_every_s` seconds
and, at the end, a last checkpoint and summary.json. A run whose params adapt the attitude assist
(robot_rl.runs.curriculum) has its curriculum here too: the ledger counts the falls, tells the trainer's env the
new scale, logs it, and keeps it in the TrainingState. When the run cannot go on (Ctrl-C, the sim gone,
an error), `saved_on_stop` writes a checkpoint and a summary marked incomplete (a failure to write is
logged, not raised) before the error goes on. What a checkpoint holds, the agent's own words in the
log lines and its own summary entries come from the trainer (`Learner`).
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol

from ..params import AttitudeAssist
from ..task import Episode, MetricValue, TaskSpec
from .curriculum import AssistCurriculum, needs_the_env_in_process
from .results import EpisodeRecord, RunDirectory, aggregate

PROGRESS_WINDOW = 50   # episodes the progress line's headline metric is averaged over
ETA_WINDOW = 10        # the latest episodes whose mean length the ETA assumes for the episodes to come
SUMMARY_WINDOW = 100   # episodes summary.json's metrics are averaged over


@dataclass
class TrainingState:
    """Everything a checkpoint holds besides the agent, so a resumed run continues seamlessly."""

    episode: int = 0                      # episodes completed
    highest_reward: float = 0.0
    last_time_steps: list[int] = field(default_factory=list)  # lengths of episodes that ended terminated
    sim_time: float = 0.0
    wall_time: float = 0.0
    env_steps: int = 0
    assist_scale: float | None = None     # the attitude assist's curriculum (None: the run has none)
    assist_window: list[int] = field(default_factory=list)  # its window under way: 1 per episode that fell

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> TrainingState:
        state = cls(**values)
        numbers = (state.highest_reward, state.sim_time, state.wall_time)
        if not (isinstance(state.episode, int) and state.episode >= 0 and isinstance(state.env_steps, int)
                and all(isinstance(v, (int, float)) and math.isfinite(v) for v in numbers)
                and isinstance(state.last_time_steps, list)
                and all(isinstance(v, int) for v in state.last_time_steps)
                and (state.assist_scale is None or isinstance(state.assist_scale, (int, float)))
                and isinstance(state.assist_window, list)):
            raise ValueError(f"the training state {values!r} has wrong types")
        return state


def restored_state(checkpoint: dict[str, Any], checkpoint_format: str, task: TaskSpec[Any]) -> TrainingState:
    """The counters of a checkpoint of `checkpoint_format` and `task` (ValueError/KeyError/TypeError if not)."""
    if checkpoint.get("format") != checkpoint_format:
        raise ValueError(f"format is {checkpoint.get('format')!r}, expected {checkpoint_format!r}")
    if checkpoint["task"] not in task.env_ids:
        raise ValueError(f"it is of task {checkpoint['task']!r}, this run trains {task.env_id!r}")
    state = TrainingState.from_dict(checkpoint["state"])
    if checkpoint["episode"] != state.episode:
        raise ValueError(f"episode {checkpoint['episode']!r} differs from the state's {state.episode}")
    return state


def format_duration(seconds: float) -> str:
    """H:MM:SS; "?" for a duration not known yet (NaN)."""
    if not math.isfinite(seconds):
        return "?"
    h, rest = divmod(int(seconds), 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}"


def _no_op(*_args: Any) -> None:
    return None


def _never() -> bool:
    return False


@dataclass(frozen=True)
class TrainingHooks:
    """How a trainer talks to whoever runs it (the training node, a test, the bench)."""

    log: Callable[[str], None] = print
    log_episode: Callable[[str], None] | None = None   # the "EP:" lines; None: `log`
    on_step: Callable[[float, float], None] = _no_op   # (reward, return so far) after every env step
    on_episode: Callable[[float], None] = _no_op       # the return of every episode that ended
    should_stop: Callable[[], bool] = _never            # asked between steps: end the run early
    checkpoint_every: int = 10                          # episodes
    progress_every_s: float = 10.0


DEFAULT_HOOKS = TrainingHooks()


class Learner(Protocol):
    """What a RunLedger asks of its trainer."""

    def save_checkpoint(self) -> None:
        """Write the run's checkpoint (the agent and `state`), each file whole."""

    def episode_label(self, epsilon: float) -> str:
        """The bracket of an "EP:" line, for an episode that ended with exploration rate `epsilon`."""

    def exploration_label(self) -> str:
        """The end of a progress line: the exploration rate now (", epsilon 0.771"), or ""."""

    def summary_fields(self) -> dict[str, Any]:
        """The agent's own entries of summary.json."""

    def closing_lines(self, summary: dict[str, Any], last: Sequence[EpisodeRecord]) -> list[str]:
        """What to log once summary.json is written (`last`: the episodes it averages over)."""


class RunLedger:
    """The bookkeeping of `run`, trained on `task` for `nepisodes` episodes from `n_envs` envs.

    `count_env_steps`, if given, counts the env steps itself (SB3's num_timesteps, which include the
    steps of episodes under way); otherwise they are the steps of the episodes that ended. With a
    budget of `max_steps` env steps, the progress line counts steps instead of episodes. `assist`: the run's
    attitude assist params; when they adapt, `set_assist` hands each new scale (0 for an episode the curriculum
    trains free) to the trainer's env (ValueError when the trainer has none to give: its envs cannot change the
    assist during a run)."""

    def __init__(self, run: RunDirectory, task: TaskSpec[Any], nepisodes: int, state: TrainingState, learner: Learner,
                 hooks: TrainingHooks, n_envs: int = 1, count_env_steps: Callable[[], int] | None = None,
                 max_steps: int | None = None, assist: AttitudeAssist | None = None,
                 set_assist: Callable[[float], None] | None = None):
        self.run, self.task, self.nepisodes, self.state, self.learner = run, task, nepisodes, state, learner
        self.log, self.log_episode = hooks.log, hooks.log_episode or hooks.log
        self.on_episode, self.should_stop = hooks.on_episode, hooks.should_stop
        self.checkpoint_every, self.progress_every_s = hooks.checkpoint_every, hooks.progress_every_s
        self.n_envs, self.count_env_steps, self.max_steps = n_envs, count_env_steps, max_steps
        self.episodes_per_env = [0] * n_envs
        self.curriculum: AssistCurriculum | None = None
        self._assist_given: float | None = None  # the scale last handed to the env
        if assist is not None and assist.adapt_every:
            if set_assist is None:
                raise ValueError(needs_the_env_in_process(assist))
            try:
                self.curriculum = AssistCurriculum(assist, state.assist_scale, state.assist_window)
            except ValueError as error:
                raise ValueError(f"{run.checkpoint_json}: {error}") from None
            self.set_assist = set_assist
            state.assist_scale = self.curriculum.scale

    def start(self) -> None:
        """Start the clocks (a resumed run's wall time goes on) and read the recent headline metrics."""
        now = time.monotonic()
        self._started, self._start_episode, self._start_steps = now, self.state.episode, self.state.env_steps
        self._wall_start, self._next_progress = now - self.state.wall_time, now + self.progress_every_s
        recent = self.run.read_episodes()[-PROGRESS_WINDOW:]
        self.headline: list[MetricValue] = [r.metrics.get(self.task.headline_metric, math.nan) for r in recent]
        self.recent_lengths = [r.steps for r in recent[-ETA_WINDOW:]]
        if self.curriculum is not None:  # a resumed run's scale, where its checkpoint left it
            self._assist_given = self.curriculum.scale_of(self.state.episode + 1)
            self.set_assist(self._assist_given)

    def episode_done(self, episode: Episode, highest: float, epsilon: float, env_index: int = 0) -> None:
        """Count an ended episode of env `env_index` (`highest`: its highest return so far, `epsilon` its
        exploration rate), write its row and its "EP:" line, and a checkpoint when one is due."""
        state = self.state
        metrics = self.task.metrics(episode)
        self.headline = [*self.headline[-PROGRESS_WINDOW + 1:], metrics[self.task.headline_metric]]
        self.recent_lengths = [*self.recent_lengths[-ETA_WINDOW + 1:], episode.steps]
        self.episodes_per_env[env_index] += 1
        state.highest_reward = max(state.highest_reward, highest)
        if episode.terminated:
            state.last_time_steps.append(episode.steps)
        state.episode += 1
        if self.count_env_steps is None:
            state.env_steps += episode.steps
        state.sim_time += episode.duration
        state.wall_time = time.monotonic() - self._wall_start
        self.run.append_episode(EpisodeRecord(episode=state.episode, steps=episode.steps, return_=episode.return_,
                                              epsilon=epsilon, sim_time=state.sim_time, wall_time=state.wall_time,
                                              metrics=metrics))
        self.on_episode(episode.return_)
        self._adapt_assist(episode.terminated)
        per_env = f" - env {env_index + 1}/{self.n_envs} (episodes per env: " \
                  f"{', '.join(map(str, self.episodes_per_env))})" if self.n_envs > 1 else ""
        self.log_episode(f"EP: {state.episode} - [{self.learner.episode_label(epsilon)}] - Reward: "
                         f"{episode.return_:.1f}     Time: {format_duration(state.wall_time)}{per_env}")
        if state.episode % self.checkpoint_every == 0:
            self.checkpoint()

    def _adapt_assist(self, fell: bool) -> None:
        """Count the episode in the assist's curriculum; a new scale goes to the env and the log."""
        curriculum = self.curriculum
        if curriculum is None:
            return
        previous, ended = curriculum.scale, self.state.episode
        if curriculum.episode_ended(ended, fell):
            self.log(f"attitude assist: scale {previous:.4g} -> {curriculum.scale:.4g} after episode "
                     f"{ended} ({curriculum.last_falls} of the last {curriculum.assist.adapt_every} "
                     f"{'assisted ' if curriculum.assist.free_share else ''}episodes fell)")
        given = curriculum.scale_of(ended + 1)
        if given != self._assist_given:
            self.set_assist(given)
            self._assist_given = given
        self.state.assist_scale, self.state.assist_window = curriculum.scale, list(curriculum.window)

    def checkpoint_due(self) -> bool:
        """Whether the next episode that ends brings a checkpoint."""
        return (self.state.episode + 1) % self.checkpoint_every == 0

    def sync_env_steps(self) -> None:
        if self.count_env_steps is not None:
            self.state.env_steps = self.count_env_steps()

    def checkpoint(self) -> None:
        """The trainer's checkpoint, then learning_curve.png."""
        self.sync_env_steps()
        self.learner.save_checkpoint()
        self.run.write_learning_curve(self.task.headline_metric, *self.task.curve_metrics)

    def log_progress_if_due(self) -> None:
        """A progress line (episodes, rate, ETA, the headline metric) every progress_every_s seconds."""
        now = time.monotonic()
        if now < self._next_progress:
            return
        self._next_progress = now + self.progress_every_s
        self.sync_env_steps()
        state = self.state
        unit, count, total = ("step", state.env_steps, self.max_steps) if self.max_steps \
            else ("episode", state.episode, self.nepisodes)
        eta = self.eta_s(now)
        name, value = next(iter(aggregate({self.task.headline_metric: self.headline}).items()))
        self.log(f"progress: {unit} {count}/{total} ({100.0 * count / total:.0f} %), "
                 f"{state.env_steps / max(now - self._wall_start, 1e-9):.0f} env steps/s, ETA {format_duration(eta)}, "
                 f"{name} over the last {len(self.headline)} episodes: {'n/a' if value is None else f'{value:.3g}'}"
                 f"{self.learner.exploration_label()}"
                 f"{'' if self.curriculum is None else f', attitude assist scale {self.curriculum.scale:.3g}'}")

    def eta_s(self, now: float) -> float:
        """Seconds left (NaN until known): the env steps left at this run's env step rate. Without a step budget,
        the steps left are the episodes left times the mean length of the latest ETA_WINDOW episodes: episodes
        grow as an agent learns, and the early ones' time per episode would promise too soon an end."""
        steps = self.state.env_steps - self._start_steps
        if steps <= 0 or now <= self._started:
            return math.nan
        rate = steps / (now - self._started)
        left: float
        if self.max_steps:
            left = self.max_steps - self.state.env_steps
        elif self.recent_lengths:
            left = (self.nepisodes - self.state.episode) * sum(self.recent_lengths) / len(self.recent_lengths)
        else:
            return math.nan
        return max(left, 0) / rate

    @contextmanager
    def saved_on_stop(self, rollback: Callable[[], None] = _no_op) -> Iterator[None]:
        """On any error in the block: `rollback` (back to where the counters are), a checkpoint and a
        summary marked incomplete ("interrupted" on Ctrl-C or a stop request, else "error: ..."), then
        the error goes on."""
        try:
            yield
        except BaseException as error:
            rollback()
            self._save_quietly("interrupted" if isinstance(error, KeyboardInterrupt) or self.should_stop()
                               else f"error: {error}")
            raise

    def _save_quietly(self, reason: str) -> None:
        """Checkpoint and summary (incomplete, `reason`), each if it can be written (on a full disk the small
        summary may be, when the checkpoint is not); a failure to write is logged, not raised."""
        for what, save in (("checkpoint", self.checkpoint), ("summary", lambda: self.finish(stopped=reason))):
            try:
                save()
            except (OSError, ValueError) as error:  # the original error matters more; say what was not saved
                self.log(f"could not save the run's {what} after episode {self.state.episode}: {error}")

    def close(self, done: bool, stopped: str | None = None) -> dict[str, Any]:
        """The last checkpoint and summary.json: complete if `done` and not `stopped`, else "interrupted"
        or `stopped`. Returns the summary."""
        self.state.wall_time = time.monotonic() - self._wall_start
        self.checkpoint()
        return self.finish(stopped=None if done and stopped is None else stopped or "interrupted")

    def finish(self, stopped: str | None = None) -> dict[str, Any]:
        """summary.json (`stopped` says why a run ended before its last episode), then the trainer's closing lines
        (logged as the "EP:" lines are)."""
        self.sync_env_steps()
        state = self.state
        last = self.run.read_episodes()[-SUMMARY_WINDOW:]
        metrics = aggregate({name: [r.metrics[name] for r in last] for name in self.run.metric_names})
        summary = {"task": self.task.env_id, "robot": self.run.robot, "run": self.run.name,
                   "episodes": state.episode, "nepisodes": self.nepisodes, "highest_reward": state.highest_reward,
                   **self.learner.summary_fields(),
                   "mean_return_last_100": aggregate({"return": [r.return_ for r in last]})["mean_return"],
                   "metrics_last_100": metrics, "headline_metric": self.task.headline_metric,
                   "env_steps": state.env_steps, "sim_time_s": state.sim_time, "wall_time_s": state.wall_time,
                   "env_steps_per_s": state.env_steps / state.wall_time if state.wall_time > 0 else None,
                   "completed": stopped is None, "stopped": stopped,
                   **({} if self.curriculum is None else {"attitude_assist_scale": self.curriculum.scale})}
        self.run.write_summary(summary)
        for line in self.learner.closing_lines(summary, last):
            self.log_episode(line)  # the tutorial's table row and scores: with the EP: lines
        return summary
