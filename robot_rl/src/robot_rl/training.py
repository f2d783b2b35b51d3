"""The tutorials' Q-learning loop, shared by both robots, with results on disk and resume.

Per episode, as in the tutorials' start_training scripts: decay epsilon (while > 0.05), reset, then
up to nsteps of chooseAction -> env.step -> learn, and one log line "EP: ...". Past the tutorials:
terminal transitions do not bootstrap, the step cap is gymnasium truncation, every episode is
appended to episodes.csv, a checkpoint (Q-table, epsilon, RNG, counters; JSON, atomic) is written
every `checkpoint_every` episodes and at the end, and a run can resume from its last checkpoint:
episodes logged after it are dropped and re-run, never repeated.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, List, Optional

import numpy as np

from .discretiser import Discretiser
from .qlearn import QLearn
from .results import EpisodeRecord, RunDirectory

CHECKPOINT_FORMAT = "robot_rl.training_checkpoint/1"


@dataclass
class TrainingConfig:
    alpha: float
    gamma: float
    epsilon: float
    epsilon_discount: float
    nepisodes: int
    nsteps: int
    seed: int = 0
    checkpoint_every: int = 10


@dataclass
class TrainingState:
    """Everything a checkpoint holds besides the Q-table, so a resumed run continues seamlessly."""

    episode: int = 0                      # episodes completed
    highest_reward: float = 0.0
    last_time_steps: List[int] = field(default_factory=list)  # lengths of episodes that ended terminated
    sim_time: float = 0.0
    wall_time: float = 0.0
    env_steps: int = 0


def _no_op(*_args) -> None:
    return None


class QLearningTrainer:
    """Runs the loop on a gymnasium env whose observations `discretiser` turns into state keys."""

    def __init__(self, env, discretiser: Discretiser, config: TrainingConfig, run: RunDirectory,
                 log: Callable[[str], None] = print, on_step: Callable[[float, float], None] = _no_op,
                 on_episode: Callable[[float], None] = _no_op, should_stop: Callable[[], bool] = lambda: False,
                 resume: bool = False):
        self.env, self.discretiser, self.config, self.run = env, discretiser, config, run
        self.log, self.on_step, self.on_episode, self.should_stop = log, on_step, on_episode, should_stop
        if resume:
            checkpoint = run.prepare_resume()
            if checkpoint.get("format") != CHECKPOINT_FORMAT:
                raise ValueError(f"{run.qtable_json}: not a training checkpoint of this version")
            self.qlearn = QLearn.from_dict(checkpoint["qlearn"])
            self.state = TrainingState(**checkpoint["state"])
            self.initial_epsilon = checkpoint["initial_epsilon"]
            log(f"Resuming {run.path} after episode {self.state.episode} (epsilon {self.qlearn.epsilon:.4f})")
        else:
            self.qlearn = QLearn(actions=list(range(env.action_space.n)), epsilon=config.epsilon,
                                 alpha=config.alpha, gamma=config.gamma, seed=config.seed)
            self.state = TrainingState()
            self.initial_epsilon = config.epsilon

    def checkpoint(self) -> None:
        self.run.checkpoint({"format": CHECKPOINT_FORMAT, "episode": self.state.episode,
                             "qlearn": self.qlearn.to_dict(), "discretiser": self.discretiser.to_dict(),
                             "initial_epsilon": self.initial_epsilon, "state": vars(self.state)})
        self.run.write_learning_curve()

    def _episode(self, first: bool) -> tuple:
        qlearn, env = self.qlearn, self.env
        if qlearn.epsilon > 0.05:
            qlearn.epsilon *= self.config.epsilon_discount
        # The first episode of a (resumed) run restarts sim time and sensor noise from the seeds.
        observation, _ = env.reset(seed=self.config.seed if first else None)
        state = self.discretiser.key(observation)
        cumulated = 0.0
        steps = 0
        for i in range(self.config.nsteps):
            action = qlearn.chooseAction(state)
            observation, reward, terminated, truncated, _ = env.step(action)
            steps = i + 1
            cumulated += reward
            self.state.highest_reward = max(self.state.highest_reward, cumulated)
            next_state = self.discretiser.key(observation)
            qlearn.learn(state, action, reward, next_state, terminal=terminated)
            self.on_step(reward, cumulated)
            if terminated:
                self.state.last_time_steps.append(steps)
            if terminated or truncated:
                break
            state = next_state
        return steps, cumulated

    def train(self) -> dict:
        """Run the remaining episodes; returns the summary written to summary.json."""
        config, state = self.config, self.state
        wall_start = time.monotonic() - state.wall_time
        first = True
        while state.episode < config.nepisodes and not self.should_stop():
            steps, cumulated = self._episode(first)
            first = False
            state.episode += 1
            state.env_steps += steps
            state.sim_time += steps * self.env.unwrapped.running_step
            state.wall_time = time.monotonic() - wall_start
            self.run.append_episode(EpisodeRecord(episode=state.episode, steps=steps, return_=cumulated,
                                                  epsilon=self.qlearn.epsilon, sim_time=state.sim_time,
                                                  wall_time=state.wall_time))
            self.on_episode(cumulated)
            h, rest = divmod(int(state.wall_time), 3600)
            m, s = divmod(rest, 60)
            self.log(f"EP: {state.episode} - [alpha: {round(self.qlearn.alpha, 2)} - gamma: "
                     f"{round(self.qlearn.gamma, 2)} - epsilon: {round(self.qlearn.epsilon, 2)}] - Reward: "
                     f"{cumulated:.1f}     Time: {h}:{m:02d}:{s:02d}")
            if state.episode % config.checkpoint_every == 0:
                self.checkpoint()
        self.checkpoint()
        return self.finish()

    def finish(self) -> dict:
        """The tutorials' closing lines (without their reduce and division-by-zero bugs) + summary.json."""
        state, qlearn = self.state, self.qlearn
        self.log(f"\n|{self.config.nepisodes}|{qlearn.alpha}|{qlearn.gamma}|{self.initial_epsilon}*"
                 f"{self.config.epsilon_discount}|{state.highest_reward}| PICTURE |")
        lengths = sorted(state.last_time_steps)
        overall = float(np.mean(lengths)) if lengths else None
        best_100 = float(np.mean(lengths[-100:])) if lengths else None
        fmt = (lambda v: "n/a (no episode ended by termination)" if v is None else f"{v:0.2f}")
        self.log(f"Overall score: {fmt(overall)}")
        self.log(f"Best 100 score: {fmt(best_100)}")
        returns = [r.return_ for r in self.run.read_episodes()]
        summary = {"robot": self.run.robot, "run": self.run.name, "episodes": state.episode,
                   "nepisodes": self.config.nepisodes, "highest_reward": state.highest_reward,
                   "overall_score": overall, "best_100_score": best_100,
                   "mean_return_last_100": float(np.mean(returns[-100:])) if returns else None,
                   "env_steps": state.env_steps, "sim_time_s": state.sim_time, "wall_time_s": state.wall_time,
                   "env_steps_per_s": state.env_steps / state.wall_time if state.wall_time > 0 else None,
                   "q_table_entries": len(qlearn.q), "final_epsilon": qlearn.epsilon,
                   "completed": state.episode >= self.config.nepisodes}
        self.run.write_summary(summary)
        return summary


def make_trainer_config(params: dict, checkpoint_every: int = 10) -> TrainingConfig:
    return TrainingConfig(alpha=params["alpha"], gamma=params["gamma"], epsilon=params["epsilon"],
                          epsilon_discount=params["epsilon_discount"], nepisodes=params["nepisodes"],
                          nsteps=params["nsteps"], seed=params.get("seed", 0), checkpoint_every=checkpoint_every)

