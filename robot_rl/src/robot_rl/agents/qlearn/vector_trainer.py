"""Tabular Q-learning from N envs into one Q-table: the vector path beside QLearningTrainer's single env,
and the agent registry's `make_trainer`, which picks one of the two.

The N envs (the workers of a robot_rl.workers.vector_env.RobotVectorEnv, autoreset SAME_STEP) step side by side:
the trainer takes their replies in env order, round and round, learns each transition, and sends that
env its next action at once (chosen from the one table with the one seeded RNG), before it writes an
ended episode down. The envs are not stepped together as a vector env's are, but an env's reply waits
until the replies before it in that order have been taken: the order of every choice and update is
fixed, so a run repeats. Each episode that starts decays epsilon as the single-env loop does before
each episode, so epsilon follows the same schedule per episode; training ends when nepisodes episodes
have ended (the episodes still under way then are dropped). The trainer's RunLedger writes the ended
episodes in the order they end, with the same files as one env's (episodes.csv, qtable.json,
learning_curve.png, summary.json) and "EP:" lines that name the env and each env's episode count,
while that env takes its next step (before it when a checkpoint is due: the checkpoint holds the
table before the next action is chosen). A checkpoint holds the Q-table with the steps of the episodes
under way at that moment: resume continues from it (those episodes start anew), so with N > 1 a
resumed run is not bit-for-bit an uninterrupted one. When the envs fail or the run is stopped, the
Q-table as it is and a summary marked incomplete are saved. An env whose worker was lost and replaced
(a Ray actor restarted on another node: robot_rl.workers.ray_actors, WorkerRestarted) starts the episode it had
under way anew from the new worker's first observation, as after a resume; no episode is lost or repeated.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium

from ...params import Params, TaskParams
from ...runs.ledger import DEFAULT_HOOKS, TrainingHooks
from ...runs.results import RunDirectory
from ...task import Episode, TaskSpec, episode_duration
from ...workers.base import WorkerRestarted
from ...workers.vector_env import RobotVectorEnv
from ..registry import AgentSpec
from .trainer import QLearningTrainer


class VectorQLearningTrainer(QLearningTrainer):
    """QLearningTrainer's Q-learner and ledger, trained from the N envs of `env`."""

    env: RobotVectorEnv  # type: ignore[assignment]  # QLearningTrainer's env, N of them

    def __init__(self, env: RobotVectorEnv, task: TaskSpec[Any], params: TaskParams, run: RunDirectory,
                 hooks: TrainingHooks = DEFAULT_HOOKS, resume: bool = False):
        if params.selection.every:
            raise ValueError(f"selection/every {params.selection.every}: the table checks play one env; the "
                             f"{env.num_envs} envs of a vector env train without them (set it to 0, or envs:=1)")
        super().__init__(env, task, params, run, hooks, resume)  # type: ignore[arg-type]  # N envs, as `env` above

    def train(self) -> dict[str, Any]:
        if self._resuming:
            self._hooks.log(self._resuming)
        self.ledger.start()
        with self.ledger.saved_on_stop():
            self._train()
        return self.ledger.close(done=self.state.episode >= self.params.nepisodes)

    def _train(self) -> None:
        params, state, qlearn, env, n = self.params, self.state, self.qlearn, self.env, self.env.num_envs
        ledger = self.ledger
        started = state.episode
        observations, _ = env.reset(seed=params.seed)  # each env's first episode restarts its sim from its seed
        keys = [self.state_key.key(o) for o in observations]
        active = [False] * n  # whether env i runs an episode that counts
        for i in range(n):
            if started < params.nepisodes:
                self.decay_epsilon()
                active[i], started = True, started + 1
        returns, steps = [0.0] * n, [0] * n
        highest = [-math.inf] * n
        actions, in_flight = [0] * n, [False] * n  # env i's last action; whether its step is under way

        def send(i: int) -> None:
            actions[i] = qlearn.chooseAction(keys[i])
            env.workers.send(i, "step", actions[i])
            in_flight[i] = True

        for i in range(n):
            if active[i]:
                send(i)
        while any(in_flight):
            for i in range(n):
                if not in_flight[i]:
                    continue
                try:
                    observation, reward, terminated, truncated, _, final = env.workers.receive(i, what="answer a step")
                except WorkerRestarted as restart:  # the episode under way starts anew on the new worker
                    ledger.log(f"env {i + 1}/{n}: {restart}; its episode under way starts anew")
                    keys[i] = self.state_key.key(restart.observation)
                    returns[i], steps[i], highest[i] = 0.0, 0, -math.inf
                    send(i)
                    continue
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
                episode = Episode(steps=steps[i], return_=returns[i], terminated=terminated,
                                  duration=episode_duration(final[1], steps[i], self.running_step), info=final[1])
                ended = (episode, highest[i], qlearn.epsilon, i)
                returns[i], steps[i], highest[i] = 0.0, 0, -math.inf
                checkpoint_due = ledger.checkpoint_due()
                if checkpoint_due:  # the checkpoint holds the table before the next episode's first choice
                    ledger.episode_done(*ended)
                active[i] = started < params.nepisodes
                if active[i]:
                    self.decay_epsilon()
                    started += 1
                    if not self.should_stop():
                        send(i)
                if not checkpoint_due:  # while env i steps
                    ledger.episode_done(*ended)
            ledger.log_progress_if_due()


def make_trainer(agent: AgentSpec, env: gymnasium.Env[Any, Any], task: TaskSpec[Any], params: TaskParams,
                 run: RunDirectory, hooks: TrainingHooks, resume: bool, agent_params: Params | None,
                 max_steps: int | None, agent_config: Path | None) -> QLearningTrainer:
    """The tabular trainer of `env`: one env, or robot_rl.workers.vector_env's N (VectorQLearningTrainer); its
    params are the task's (no agent_params, agent_config), its budget nepisodes (no max_steps)."""
    if isinstance(env, gymnasium.vector.VectorEnv):
        return VectorQLearningTrainer(env, task, params, run, hooks, resume)
    return QLearningTrainer(env, task, params, run, hooks, resume)
