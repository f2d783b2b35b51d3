"""A Stable-Baselines3 VecEnv over env workers (robot_rl.workers: one process per env, or Ray actors).

SB3's conventions: done = terminated or truncated, the last observation in info["terminal_observation"],
info["TimeLimit.truncated"], the env reset at once. `seed(s)` gives worker i the i-th seed numpy's
SeedSequence(s) derives, as the gymnasium face does. An action travels to the env as the space holds it (an
int, or a float32 array).
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from ...params import TaskParams
from ...task import TaskSpec
from ...workers.base import Workers, as_env_actions, worker_seeds
from ...workers.factory import make_env_workers


class RobotVecEnv(VecEnv):
    """A Stable-Baselines3 VecEnv over env workers (Workers) (see the module docstring)."""

    def __init__(self, workers: Workers):
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
