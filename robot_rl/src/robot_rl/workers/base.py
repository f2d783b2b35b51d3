"""What every kind of env worker shares: its errors, seeds, recipe, env and replies, and the actions it takes.

Worker i makes the task's env with the i-th seed that numpy's SeedSequence derives from the one seed given
(worker_seeds), so a run repeats; over ROS it first starts a `PrivateSim` (rosmaster on a free loopback port +
the robot's sim node, paused) and becomes a node on that master, so every worker sees the tutorials' global
topic names; direct workers need no master. A worker resets its env the moment an episode ends (gymnasium's
SAME_STEP autoreset: the step answers the first observation of the next episode, with the last one and the
last info beside it). The same replies come from a pipe worker (robot_rl.workers.pipe) and a Ray actor
(robot_rl.workers.ray_actors).
"""
from __future__ import annotations

import os
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import gymnasium
import numpy as np

from ..envs.backends.factory import check_backend_name, make_backend, over_ros
from ..params import TaskParams
from ..task import TaskSpec, make_env
from .private_sim import PrivateSim

START_TIMEOUT = 60.0   # s for a worker to start its master, its sim node and its env
REPLY_MARGIN = 30.0    # s a worker may take beyond ros_timeout to answer (a reset with a long settle on a busy machine)
CLOSE_TIMEOUT = 10.0   # s for a worker to close before SIGTERM, and again before SIGKILL


class WorkerError(RuntimeError):
    """A worker failed, died or did not answer in time; the message names it and what to check, and
    `log_dir` the temporary folder kept for it (None: the caller's folder)."""

    def __init__(self, message: str, log_dir: Path | None = None):
        super().__init__(message)
        self.log_dir = log_dir

    def discard_logs(self) -> None:
        """Remove the temporary folder kept for the error (when it was a stop's, e.g. Ctrl-C, not a fault's)."""
        if self.log_dir is not None:
            shutil.rmtree(self.log_dir, ignore_errors=True)


class WorkerRestarted(WorkerError):
    """Worker `index` was lost and a new one took its place (a Ray actor restarted on another node): the reply
    owed is lost, the new worker's env has been reset, and `observation`, `info` are that reset's."""

    def __init__(self, message: str, index: int, observation: Any, info: dict[str, Any]):
        super().__init__(message)
        self.index, self.observation, self.info = index, observation, info


class WorkersStopped(WorkerError):
    """A stop request (stop_waits_when's check: SIGTERM or SIGINT to the training node) ended a wait on the workers;
    the workers have not failed."""


_stop_check: list[Callable[[], bool]] = []


def stop_waits_when(check: Callable[[], bool]) -> None:
    """From now on, every wait on Ray actors (robot_rl.workers.ray_actors: a start, a reply, a restart) ends with
    WorkersStopped within a slice of a second once `check()` is true (e.g. the training node's stop request)."""
    _stop_check[:] = [check]


def stop_requested() -> bool:
    """Whether stop_waits_when's check says stop (False when none is set)."""
    return any(check() for check in _stop_check)


class Workers(Protocol):
    """N env workers as the faces over them (robot_rl.workers.vector_env, robot_rl.agents.sb3.vec_env) and the
    tabular trainer from N envs use them: robot_rl.workers.pipe.EnvWorkers, robot_rl.workers.ray_actors'
    RayEnvWorkers. Worker i's replies are robot_rl.workers.base.answer's."""

    n: int
    observation_space: Any
    action_space: Any
    metadata: dict[str, Any]
    worker_info: list[dict[str, Any]]

    def send(self, i: int, command: str, data: Any = None) -> None:
        """Send worker i a command; its reply is owed until received."""

    def receive(self, i: int, timeout: float | None = None, what: str = "reply") -> Any:
        """Worker i's reply (bounded); WorkerError if it failed, died or did not answer."""

    def receive_all(self, timeout: float | None = None, what: str = "reply") -> list[Any]:
        """Every worker's reply, within `timeout` for all of them."""

    def request_all(self, command: str, data: Sequence[Any]) -> list[Any]:
        """Send worker i `command` with data[i], then every reply."""

    def close(self) -> None:
        """End every worker and what it started (bounded; idempotent)."""


def worker_seeds(seed: int | None, n: int) -> list[int]:
    """N independent seeds in [0, 2**31) (ROS params are 32-bit ints) derived from one by numpy's
    SeedSequence.spawn: the same seed gives the same N seeds; None draws fresh entropy."""
    return [int(child.generate_state(1, dtype=np.uint32)[0] >> 1) for child in np.random.SeedSequence(seed).spawn(n)]


@dataclass(frozen=True)
class WorkerRecipe:
    """What a worker needs to make its env (pickled to the spawned process)."""

    task: TaskSpec[Any]
    params: TaskParams
    backend: str                  # "ros" or "direct"
    seed: int
    ros_timeout: float
    log_dir: Path
    own_log_dir: bool             # a temporary folder of the parent's, which nobody would remove if it died
    max_episode_steps: int | None
    env_kwargs: dict[str, Any]


def worker_env(index: int, recipe: WorkerRecipe) -> tuple[gymnasium.Env[Any, Any], PrivateSim | None]:
    """The worker's env, over its own private sim when over ROS."""
    if not over_ros(recipe.backend):
        return make_env(recipe.task, params=recipe.params, backend=recipe.backend, seed=recipe.seed,
                        max_episode_steps=recipe.max_episode_steps, **recipe.env_kwargs), None
    sim = PrivateSim(recipe.task.robot, recipe.log_dir / f"worker{index}", seed=recipe.seed)
    try:
        os.environ.update(ROS_MASTER_URI=sim.uri, ROS_HOSTNAME="127.0.0.1", ROS_IP="127.0.0.1",
                          ROS_LOG_DIR=str(sim.log_dir), ROS_HOME=str(sim.log_dir))
        import rospy
        rospy.init_node(f"robot_rl_worker{index}", disable_signals=True)  # the parent decides when a worker ends
        backend = make_backend(recipe.backend, recipe.task.robot, timeout=recipe.ros_timeout,
                               hint=f"the worker's sim node (pid {sim.processes[-1].pid}) is gone or frozen: its log "
                                    f"is {sim.log_dir / 'sim_node.log'}")
        env = make_env(recipe.task, params=recipe.params, backend=backend, ros_timeout=recipe.ros_timeout,
                       max_episode_steps=recipe.max_episode_steps, **recipe.env_kwargs)
    except BaseException:
        sim.close()
        raise
    return env, sim


def answer(env: gymnasium.Env[Any, Any], command: str, data: Any) -> Any:
    """A worker's reply to a command other than "close" (the same over a pipe and as a Ray actor)."""
    if command == "step":
        observation, reward, terminated, truncated, info = env.step(data)
        final = None
        if terminated or truncated:
            final = (observation, info)
            observation, info = env.reset()
        return observation, float(reward), bool(terminated), bool(truncated), info, final
    if command == "reset":
        return env.reset(seed=data[0], options=data[1])
    if command == "get_attr":
        return getattr(env.unwrapped, data)
    if command == "call":
        name, args, kwargs = data
        return getattr(env.unwrapped, name)(*args, **kwargs)
    raise ValueError(f"unknown worker command {command!r}")


def check_workers(n: Any, backend: str) -> None:
    """ValueError unless `n` envs over `backend` can be made."""
    if not (isinstance(n, int) and n >= 1):
        raise ValueError(f"the number of envs must be a whole number >= 1, got {n!r}")
    check_backend_name(backend)


def as_env_actions(actions: Any, space: gymnasium.spaces.Space[Any], n: int) -> list[Any]:
    """`actions` (a batch, as an agent gives it) as `n` single actions in the form `space` holds: ints for
    Discrete, float32 arrays of the space's shape for Box. ValueError if there are not `n` of them."""
    values = np.asarray(actions)
    if isinstance(space, gymnasium.spaces.Box):
        shape = space.shape or ()
        if values.size != n * int(np.prod(shape)):
            raise ValueError(f"{values.size} action values for {n} envs of {space}: {actions!r}")
        return [np.asarray(a, dtype=space.dtype) for a in values.reshape((n, *shape))]
    if values.size != n:
        raise ValueError(f"{values.size} actions for {n} envs: {actions!r}")
    return [int(a) if isinstance(space, gymnasium.spaces.Discrete) and np.issubdtype(a.dtype, np.integer) else a
            for a in values.reshape(n)]


def checked_actions(actions: Any, space: gymnasium.spaces.Space[Any], n: int) -> list[Any]:
    """One action per env, each checked against `space` before any is sent: a bad action is a ValueError
    naming it and its env, and no worker steps (or fails on it)."""
    checked = as_env_actions(actions, space, n)
    for i, action in enumerate(checked):
        if not space.contains(action):
            raise ValueError(f"action {np.asarray(action).tolist()!r} of env {i} is not in {space}")
    return checked
