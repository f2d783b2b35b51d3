"""Tabular Q-learning from N envs into one Q-table: the vector path beside QLearningTrainer's single env.

The N envs (the workers of a robot_rl.vector.RobotVectorEnv, autoreset SAME_STEP) step side by side:
the trainer takes their replies in env order, round and round, learns each transition, and sends that
env its next action at once (chosen from the one table with the one seeded RNG), before it writes an
ended episode down. The envs are not stepped together as a vector env's are, but an env's reply waits
until the replies before it in that order have been taken: the order of every choice and update is
fixed, so a run repeats. Each episode that starts decays epsilon as the single-env loop does before
each episode, so epsilon follows the same schedule per episode; training ends when nepisodes episodes
have ended (the episodes still under way then are dropped). Episodes are logged in the order they
end, with the same files (episodes.csv, qtable.json, learning_curve.png, summary.json) and one "EP:"
line per episode that names its env and each env's episode count, written while that env takes its
next step (before it when a checkpoint is due: the checkpoint holds the table before the next action
is chosen). A checkpoint holds the Q-table with the steps of the episodes under way at that moment:
resume continues from it (those episodes start anew), so with N > 1 a resumed run is not bit-for-bit
an uninterrupted one. When the envs fail or the run is stopped, the Q-table as it is and a summary
marked incomplete are saved.
"""
from __future__ import annotations

import math
import time
from typing import Any

from .results import EpisodeRecord
from .task import Episode, MetricValue
from .training import PROGRESS_WINDOW, QLearningTrainer, format_duration
from .vector import RobotVectorEnv


class VectorQLearningTrainer(QLearningTrainer):
    """QLearningTrainer's results, checkpoints and summary, trained from the N envs of `env`."""

    env: RobotVectorEnv  # type: ignore[assignment]  # QLearningTrainer's env, N of them

    def _decay_epsilon(self) -> None:
        if self.qlearn.epsilon > self.params.epsilon_min:
            self.qlearn.epsilon *= self.params.epsilon_discount

    def train(self) -> dict[str, Any]:
        try:
            self._train()
        except KeyboardInterrupt:
            self._save_quietly("interrupted")
            raise
        except Exception as error:
            self._save_quietly("interrupted" if self.should_stop() else f"error: {error}")
            raise
        self.checkpoint()
        return self.finish(stopped=None if self.state.episode >= self.params.nepisodes else "interrupted")

    def _train(self) -> None:
        params, state, qlearn, env, n = self.params, self.state, self.qlearn, self.env, self.env.num_envs
        wall_start = time.monotonic() - state.wall_time
        start_episode, start_wall = state.episode, time.monotonic()
        next_progress = start_wall + self.progress_every_s
        headline: list[MetricValue] = [r.metrics.get(self.task.headline_metric, math.nan)
                                       for r in self.run.read_episodes()[-PROGRESS_WINDOW:]]
        started = state.episode
        observations, _ = env.reset(seed=params.seed)  # each env's first episode restarts its sim from its seed
        keys = [self.state_key.key(o) for o in observations]
        active = [False] * n  # whether env i runs an episode that counts
        for i in range(n):
            if started < params.nepisodes:
                self._decay_epsilon()
                active[i], started = True, started + 1
        returns, steps, per_env = [0.0] * n, [0] * n, [0] * n
        highest = [-math.inf] * n
        actions, in_flight = [0] * n, [False] * n  # env i's last action; whether its step is under way

        def send(i: int) -> None:
            actions[i] = qlearn.chooseAction(keys[i])
            env.workers.send(i, "step", actions[i])
            in_flight[i] = True

        def end_episode(i: int, episode: Episode, highest_return: float, epsilon: float) -> None:
            """Count env i's ended episode (its `epsilon`), write its row and its EP line."""
            nonlocal headline
            metrics = self.task.metrics(episode)
            headline = [*headline[-PROGRESS_WINDOW + 1:], metrics[self.task.headline_metric]]
            state.highest_reward = max(state.highest_reward, highest_return)
            if episode.terminated:
                state.last_time_steps.append(episode.steps)
            state.episode += 1
            state.env_steps += episode.steps
            state.sim_time += episode.duration
            state.wall_time = time.monotonic() - wall_start
            self.run.append_episode(EpisodeRecord(episode=state.episode, steps=episode.steps, return_=episode.return_,
                                                  epsilon=epsilon, sim_time=state.sim_time, wall_time=state.wall_time,
                                                  metrics=metrics))
            self.on_episode(episode.return_)
            self.log_episode(f"EP: {state.episode} - [alpha: {round(qlearn.alpha, 2)} - gamma: "
                             f"{round(qlearn.gamma, 2)} - epsilon: {round(epsilon, 2)}] - Reward: "
                             f"{episode.return_:.1f}     Time: {format_duration(state.wall_time)} - env "
                             f"{i + 1}/{n} (episodes per env: {', '.join(map(str, per_env))})")

        for i in range(n):
            if active[i]:
                send(i)
        while any(in_flight):
            for i in range(n):
                if not in_flight[i]:
                    continue
                observation, reward, terminated, truncated, _, final = env.workers.receive(i, what="answer a step")
                in_flight[i] = False
                done = terminated or truncated
                next_key = self.state_key.key(final[0] if done else observation)
                qlearn.learn(keys[i], actions[i], reward, next_key, terminal=terminated)
                returns[i] += reward
                steps[i] += 1
                highest[i] = max(highest[i], returns[i])
                self.on_step(reward, returns[i])
                if not done:
                    keys[i] = next_key
                    if not self.should_stop():
                        send(i)
                    continue
                keys[i] = self.state_key.key(observation)  # after the reset: the next episode's first
                per_env[i] += 1
                ended = (i, Episode(steps=steps[i], return_=returns[i], terminated=terminated,
                                    duration=steps[i] * self.running_step, info=final[1]), highest[i], qlearn.epsilon)
                returns[i], steps[i], highest[i] = 0.0, 0, -math.inf
                checkpoint_due = (state.episode + 1) % self.checkpoint_every == 0
                if checkpoint_due:  # the checkpoint holds the table before the next episode's first choice
                    end_episode(*ended)
                    self.checkpoint()
                active[i] = started < params.nepisodes
                if active[i]:
                    self._decay_epsilon()
                    started += 1
                    if not self.should_stop():
                        send(i)
                if not checkpoint_due:  # while env i steps
                    end_episode(*ended)
            now = time.monotonic()
            if now >= next_progress:
                next_progress = now + self.progress_every_s
                self._log_progress(start_episode, now - start_wall, headline)
