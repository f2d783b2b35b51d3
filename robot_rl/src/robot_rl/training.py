"""The tutorials' Q-learning loop, shared by every task, with results on disk and resume.

Per episode, as in the tutorials' start_training scripts: decay epsilon (while above epsilon_min, the
tutorials' 0.05), reset, then up to nsteps of chooseAction -> env.step -> learn, and one log line
"EP: ...". Past the tutorials:
terminal transitions do not bootstrap, the step cap is gymnasium truncation, every episode is
appended to episodes.csv with the task's metrics, a progress line (rate, ETA, the task's headline
metric) is logged every few seconds, a checkpoint (Q-table, epsilon, RNG, counters; JSON, atomic)
is written every `checkpoint_every` episodes and at the end, and a run can resume from its last
checkpoint: episodes logged after it are dropped and re-run, never repeated. When an episode cannot
finish (Ctrl-C, the sim gone), the Q-learner goes back to where that episode started and a
checkpoint and a summary marked incomplete are written before the error goes on: nothing completed
is lost, and resuming repeats exactly what the uninterrupted run would have done.
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium

from .params import TaskParams
from .qlearn import QLearn
from .results import EpisodeRecord, RunDirectory, aggregate
from .task import Episode, MetricValue, TaskSpec

CHECKPOINT_FORMAT = "robot_rl.training_checkpoint/2"
PROGRESS_WINDOW = 50   # episodes the progress line's headline metric is averaged over
SUMMARY_WINDOW = 100   # episodes summary.json's metrics are averaged over


@dataclass
class TrainingState:
    """Everything a checkpoint holds besides the Q-table, so a resumed run continues seamlessly."""

    episode: int = 0                      # episodes completed
    highest_reward: float = 0.0
    last_time_steps: list[int] = field(default_factory=list)  # lengths of episodes that ended terminated
    sim_time: float = 0.0
    wall_time: float = 0.0
    env_steps: int = 0

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> TrainingState:
        state = cls(**values)
        numbers = (state.highest_reward, state.sim_time, state.wall_time)
        if not (isinstance(state.episode, int) and state.episode >= 0 and isinstance(state.env_steps, int)
                and all(isinstance(v, (int, float)) and math.isfinite(v) for v in numbers)
                and isinstance(state.last_time_steps, list)
                and all(isinstance(v, int) for v in state.last_time_steps)):
            raise ValueError(f"the training state {values!r} has wrong types")
        return state


def _no_op(*_args: Any) -> None:
    return None


def format_duration(seconds: float) -> str:
    h, rest = divmod(int(seconds), 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}"


class QLearningTrainer:
    """Runs the loop on `env`, an instance of `task` made with `params`."""

    def __init__(self, env: gymnasium.Env[Any, Any], task: TaskSpec[Any], params: TaskParams, run: RunDirectory,
                 log: Callable[[str], None] = print, log_episode: Callable[[str], None] | None = None,
                 on_step: Callable[[float, float], None] = _no_op, on_episode: Callable[[float], None] = _no_op,
                 should_stop: Callable[[], bool] = lambda: False, resume: bool = False,
                 checkpoint_every: int = 10, progress_every_s: float = 10.0):
        self.env, self.task, self.params, self.run = env, task, params, run
        self.log, self.log_episode = log, log_episode or log
        self.on_step, self.on_episode, self.should_stop = on_step, on_episode, should_stop
        self.checkpoint_every, self.progress_every_s = checkpoint_every, progress_every_s
        self.state_key = task.state_key(params)
        # A vector env's single_action_space: the action space of one of its envs.
        self.n_actions = int(getattr(env, "single_action_space", env.action_space).n)  # type: ignore[union-attr]
        self.running_step = params.running_step
        if resume:
            self.qlearn, self.state, self.initial_epsilon = run.prepare_resume(self._restore)
            log(f"Resuming {run.path} after episode {self.state.episode} (epsilon {self.qlearn.epsilon:.4f})")
        else:
            self.qlearn = QLearn(actions=range(self.n_actions), epsilon=params.epsilon, alpha=params.alpha,
                                 gamma=params.gamma, seed=params.seed, exploration=params.exploration,
                                 q_init=params.q_init, first_visit=params.first_visit)
            self.state = TrainingState()
            self.initial_epsilon = params.epsilon

    def _restore(self, checkpoint: dict[str, Any]) -> tuple[QLearn, TrainingState, float]:
        """Everything a checkpoint holds, checked against this run (ValueError/KeyError/TypeError if not)."""
        if checkpoint.get("format") != CHECKPOINT_FORMAT:
            raise ValueError(f"format is {checkpoint.get('format')!r}, expected {CHECKPOINT_FORMAT!r}")
        if checkpoint["task"] != self.task.env_id:
            raise ValueError(f"it is of task {checkpoint['task']!r}, this run trains {self.task.env_id!r}")
        if checkpoint["state_key"] != self.state_key.to_dict():
            raise ValueError("its state key differs from the one this code makes from the params")
        qlearn = QLearn.from_dict(checkpoint["qlearn"])
        if qlearn.actions != list(range(self.n_actions)):
            raise ValueError(f"its actions {qlearn.actions} are not the env's {self.n_actions}")
        state = TrainingState.from_dict(checkpoint["state"])
        if checkpoint["episode"] != state.episode:
            raise ValueError(f"episode {checkpoint['episode']!r} differs from the state's {state.episode}")
        initial_epsilon = checkpoint["initial_epsilon"]
        if not isinstance(initial_epsilon, (int, float)):
            raise ValueError(f"initial_epsilon {initial_epsilon!r} is not a number")
        return qlearn, state, float(initial_epsilon)

    def checkpoint(self) -> None:
        self.run.checkpoint({"format": CHECKPOINT_FORMAT, "task": self.task.env_id, "episode": self.state.episode,
                             "qlearn": self.qlearn.to_dict(), "state_key": self.state_key.to_dict(),
                             "initial_epsilon": self.initial_epsilon, "state": dataclasses.asdict(self.state)})
        self.run.write_learning_curve(self.task.headline_metric)

    def _episode(self, first: bool) -> tuple[Episode, float]:
        """One episode: (the episode, the highest cumulated reward within it). Changes only the Q-learner."""
        qlearn, env = self.qlearn, self.env
        if qlearn.epsilon > self.params.epsilon_min:
            qlearn.epsilon *= self.params.epsilon_discount
        # The first episode of a (resumed) run restarts sim time and sensor noise from the seeds.
        observation, _ = env.reset(seed=self.params.seed if first else None)
        state = self.state_key.key(observation)
        cumulated, highest = 0.0, -math.inf
        steps = 0
        terminated = False
        info: dict[str, Any] = {}
        for i in range(self.params.nsteps):
            action = qlearn.chooseAction(state)
            observation, step_reward, terminated, truncated, info = env.step(action)
            reward = float(step_reward)
            steps = i + 1
            cumulated += reward
            highest = max(highest, cumulated)
            next_state = self.state_key.key(observation)
            qlearn.learn(state, action, reward, next_state, terminal=terminated)
            self.on_step(reward, cumulated)
            if terminated or truncated:
                break
            state = next_state
        return Episode(steps=steps, return_=cumulated, terminated=terminated, duration=steps * self.running_step,
                       info=info), highest

    def _stop_mid_episode(self, reason: str) -> None:
        """Back to the start of the episode that could not finish, then checkpoint and summary (incomplete)."""
        self.qlearn.q, self.qlearn.epsilon, rng_state = self._episode_start
        self.qlearn.rng.setstate(rng_state)
        self._save_quietly(reason)

    def _save_quietly(self, reason: str) -> None:
        """Checkpoint and summary (incomplete, `reason`); a failure to write is logged, not raised."""
        try:
            self.checkpoint()
            self.finish(stopped=reason)
        except OSError as error:  # the original error matters more; say why nothing was saved
            self.log(f"could not save the run after episode {self.state.episode}: {error}")

    def train(self) -> dict[str, Any]:
        """Run the remaining episodes; returns the summary written to summary.json."""
        params, state = self.params, self.state
        wall_start = time.monotonic() - state.wall_time
        start_episode, start_wall = state.episode, time.monotonic()
        next_progress = start_wall + self.progress_every_s
        headline: list[MetricValue] = [r.metrics.get(self.task.headline_metric, math.nan)
                                       for r in self.run.read_episodes()[-PROGRESS_WINDOW:]]
        first = True
        while state.episode < params.nepisodes and not self.should_stop():
            self._episode_start = (dict(self.qlearn.q), self.qlearn.epsilon, self.qlearn.rng.getstate())
            try:
                episode, highest = self._episode(first)
            except KeyboardInterrupt:
                self._stop_mid_episode("interrupted")
                raise
            except Exception as error:
                self._stop_mid_episode("interrupted" if self.should_stop() else f"error: {error}")
                raise
            first = False
            state.highest_reward = max(state.highest_reward, highest)
            if episode.terminated:
                state.last_time_steps.append(episode.steps)
            metrics = self.task.metrics(episode)
            headline = [*headline[-PROGRESS_WINDOW + 1:], metrics[self.task.headline_metric]]
            state.episode += 1
            state.env_steps += episode.steps
            state.sim_time += episode.duration
            state.wall_time = time.monotonic() - wall_start
            self.run.append_episode(EpisodeRecord(episode=state.episode, steps=episode.steps, return_=episode.return_,
                                                  epsilon=self.qlearn.epsilon, sim_time=state.sim_time,
                                                  wall_time=state.wall_time, metrics=metrics))
            self.on_episode(episode.return_)
            self.log_episode(f"EP: {state.episode} - [alpha: {round(self.qlearn.alpha, 2)} - gamma: "
                             f"{round(self.qlearn.gamma, 2)} - epsilon: {round(self.qlearn.epsilon, 2)}] - Reward: "
                             f"{episode.return_:.1f}     Time: {format_duration(state.wall_time)}")
            if state.episode % self.checkpoint_every == 0:
                self.checkpoint()
            now = time.monotonic()
            if now >= next_progress:
                next_progress = now + self.progress_every_s
                self._log_progress(start_episode, now - start_wall, headline)
        self.checkpoint()
        return self.finish(stopped=None if state.episode >= params.nepisodes else "interrupted")

    def _log_progress(self, start_episode: int, elapsed: float, headline: list[MetricValue]) -> None:
        state, total = self.state, self.params.nepisodes
        done = state.episode - start_episode
        eta = (total - state.episode) * elapsed / done if done else math.nan
        value = next(iter(aggregate({self.task.headline_metric: headline}).items()))
        self.log(f"progress: episode {state.episode}/{total} ({100.0 * state.episode / total:.0f} %), "
                 f"{state.env_steps / state.wall_time:.0f} env steps/s, ETA {format_duration(eta)}, "
                 f"{value[0]} over the last {len(headline)} episodes: {value[1]:.3g}, "
                 f"epsilon {self.qlearn.epsilon:.3f}")

    def finish(self, stopped: str | None = None) -> dict[str, Any]:
        """The tutorials' closing lines (without their reduce and division-by-zero bugs) + summary.json;
        `stopped` says why a run ended before its last episode."""
        state, qlearn, params = self.state, self.qlearn, self.params
        self.log(f"\n|{params.nepisodes}|{qlearn.alpha}|{qlearn.gamma}|{self.initial_epsilon}*"
                 f"{params.epsilon_discount}|{state.highest_reward}| PICTURE |")
        lengths = sorted(state.last_time_steps)
        overall = sum(lengths) / len(lengths) if lengths else None
        best_100 = sum(lengths[-100:]) / len(lengths[-100:]) if lengths else None

        def fmt(v: float | None) -> str:
            return "n/a (no episode ended by termination)" if v is None else f"{v:0.2f}"
        self.log(f"Overall score: {fmt(overall)}")
        self.log(f"Best 100 score: {fmt(best_100)}")
        last = self.run.read_episodes()[-SUMMARY_WINDOW:]
        metrics = aggregate({name: [r.metrics[name] for r in last] for name in self.run.metric_names})
        summary = {"task": self.task.env_id, "robot": self.run.robot, "run": self.run.name,
                   "episodes": state.episode, "nepisodes": params.nepisodes, "highest_reward": state.highest_reward,
                   "overall_score": overall, "best_100_score": best_100,
                   "mean_return_last_100": aggregate({"return": [r.return_ for r in last]})["mean_return"],
                   "metrics_last_100": metrics, "headline_metric": self.task.headline_metric,
                   "env_steps": state.env_steps, "sim_time_s": state.sim_time, "wall_time_s": state.wall_time,
                   "env_steps_per_s": state.env_steps / state.wall_time if state.wall_time > 0 else None,
                   "q_table_entries": len(qlearn.q), "final_epsilon": qlearn.epsilon,
                   "completed": state.episode >= params.nepisodes and stopped is None, "stopped": stopped}
        self.run.write_summary(summary)
        return summary
