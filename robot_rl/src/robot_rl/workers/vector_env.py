"""N envs of a task as one gymnasium VectorEnv over env workers (pipe processes or Ray actors)."""
from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..params import TaskParams
from ..task import TaskSpec
from .base import Workers, checked_actions, worker_seeds
from .factory import make_env_workers


class RobotVectorEnv(VectorEnv):
    """A gymnasium VectorEnv over env workers (Workers) (autoreset SAME_STEP: infos["final_obs"], infos["final_info"]).

    reset(seed=int) resets worker i with the i-th seed SeedSequence(seed) derives (worker_seeds); a list
    gives each worker its own seed."""

    def __init__(self, workers: Workers):
        self.workers = workers
        self.num_envs = workers.n
        self.single_observation_space = workers.observation_space
        self.single_action_space = workers.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = {**workers.metadata, "autoreset_mode": AutoresetMode.SAME_STEP}
        self.spec = None
        self.render_mode = None
        self._np_random = None
        self._np_random_seed = None

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, int):
            seeds = list(worker_seeds(seed, self.num_envs))
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"reset: {len(seeds)} seeds for {self.num_envs} envs")
        replies = self.workers.request_all("reset", [(s, options) for s in seeds])
        infos: dict[str, Any] = {}
        for i, (_, info) in enumerate(replies):
            infos = self._add_info(infos, info, i)
        return np.stack([observation for observation, _ in replies]), infos

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        replies = self.workers.request_all("step", checked_actions(actions, self.single_action_space, self.num_envs))
        infos: dict[str, Any] = {}
        for i, (_, _, _, _, info, final) in enumerate(replies):
            if final is not None:
                infos = self._add_info(infos, {"final_obs": final[0], "final_info": final[1]}, i)
            infos = self._add_info(infos, info, i)
        observations = np.stack([reply[0] for reply in replies])
        rewards = np.array([reply[1] for reply in replies], dtype=np.float64)
        terminations = np.array([reply[2] for reply in replies], dtype=np.bool_)
        truncations = np.array([reply[3] for reply in replies], dtype=np.bool_)
        return observations, rewards, terminations, truncations, infos

    def close_extras(self, **kwargs: Any) -> None:
        self.workers.close()


def make_vector_env(task: TaskSpec[Any], n: int, backend: str = "ros", seed: int | None = 0,
                    params: TaskParams | None = None, cluster: str | None = None, **kwargs: Any) -> RobotVectorEnv:
    """N envs of `task` in worker processes (or Ray actors on `cluster`), as a gymnasium VectorEnv (see EnvWorkers
    for the arguments)."""
    return RobotVectorEnv(make_env_workers(task, n, cluster, backend=backend, seed=seed, params=params, **kwargs))
