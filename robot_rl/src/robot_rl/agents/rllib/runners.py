"""Agent rllib_ppo's envs: RLlib env runners on Ray, each with one env of the task and its ended episodes.

`RllibEnvs` is what the agent registry's `vector_env` gives the training node for agent rllib_ppo (envs:=N): no
env of its own on the driver, but the recipe of the N envs RLlib's env runners make (RLlib builds the runners
with the algorithm, robot_rl.agents.rllib.trainer), the task's spaces (read once from a direct env), and Ray:
joined (`cluster:=ray|HOST:PORT`, robot_rl.workers.cluster.connect, bounded) or, without a cluster, started on
this machine on loopback (127.0.0.1), its temp folder private as `./ws cluster`'s (mode 0700, Ray's folders
inside it 0700 once it is up; its own token), one CPU per runner. close() stops the algorithm (its runners, and
with each its env, master and sim node) and the Ray it started, and removes that temp folder.

Runner r (RLlib's worker_index, 1..N/K) holds K = envs_per_runner envs (a sync vector env; K is 1 over ROS), env i =
(r-1)*K + k made as env worker i makes its own (robot_rl.workers.base.worker_env: the i-th seed of worker_seeds;
over ROS a private master and sim node on its node's loopback, their logs in a temporary folder on that node: in
the temp folder of the Ray this process started, if it did, so that close() removes it also after an abandon). A
runner restarted after its node was lost makes them anew with the same seeds. `EpisodeTap` wraps that env: the agent
learns from the rewards times reward_scale, and every episode that ends is kept on the runner (steps, the task's
return, terminated, sim time, last info, the runner and its node) until the driver takes them (`take_episodes`,
after each update). The driver orders them by runner, each runner's in the order they ended: the same run repeats
the same episodes.csv.
"""
from __future__ import annotations

import contextlib
import logging
import os
import secrets
import shutil
import signal
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium

from ...params import TaskParams
from ...task import TaskSpec, episode_duration, make_env
from ...workers import cluster as ray_cluster
from ...workers.base import WorkerRecipe, check_workers, worker_env, worker_seeds

ENV_NAME = "robot_rl_task"   # the name of the env creator registered with Ray Tune
TOKEN = secrets.token_hex(32)  # the local Ray's token: one per process, as Ray reads a driver's token once
RUNNER_EXIT_TIMEOUT = 15.0  # s for the runners of a Ray started here to end after it shut down
_ENDED: list[dict[str, Any]] = []  # on a runner: the episodes ended since the driver last took them
_MADE = [0]  # on a runner: the envs its process made so far (the k-th of its K is the count mod K)


@dataclass(frozen=True)
class EndedEpisode:
    """An episode a runner ended, as the driver receives it."""

    runner: int        # RLlib's worker_index, 1..N/K
    env: int           # the env's index, 0..N-1 (its seed's in worker_seeds)
    node: str          # the runner's node's address
    node_id: str       # Ray's id of that node (nodes on one machine share its address)
    steps: int
    return_: float     # the task's (not scaled)
    terminated: bool
    duration: float    # sim s
    info: dict[str, Any]


class EpisodeTap(gymnasium.Wrapper[Any, Any, Any, Any]):
    """A runner's env: rewards times `scale` for the learner, each ended episode kept for the driver; close()
    ends the env's private sim and removes its logs."""

    def __init__(self, env: gymnasium.Env[Any, Any], runner: int, scale: float, sim: Any, log_dir: Path | None,
                 index: int = 0):
        super().__init__(env)
        import ray
        self.runner, self.index, self.scale, self.sim, self.log_dir = runner, index, scale, sim, log_dir
        self.node, self.node_id = ray.util.get_node_ip_address(), ray.get_runtime_context().get_node_id()
        self.running_step = float(getattr(env.unwrapped, "running_step", 0.0))
        self.steps, self.total = 0, 0.0

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        self.steps, self.total = 0, 0.0
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        self.steps += 1
        self.total += float(reward)
        if terminated or truncated:
            _ENDED.append({"runner": self.runner, "env": self.index, "node": self.node, "node_id": self.node_id,
                           "steps": self.steps, "return_": self.total, "terminated": bool(terminated),
                           "duration": episode_duration(info, self.steps, self.running_step), "info": dict(info)})
        return observation, float(reward) * self.scale, terminated, truncated, info

    def close(self) -> None:
        try:
            self.env.close()
        finally:
            if self.sim is not None:
                import rospy
                rospy.signal_shutdown("the env runner closes its env")
                self.sim.close()
                self.sim = None
            if self.log_dir is not None:
                shutil.rmtree(self.log_dir, ignore_errors=True)


def make_runner_env(config: Any) -> EpisodeTap:
    """RLlib's env creator (registered as ENV_NAME): the next of runner config.worker_index's envs (see the module
    docstring)."""
    recipe: WorkerRecipe = config["recipe"]
    runner, per_runner = max(1, int(config.worker_index)), int(config.get("envs_per_runner", 1))
    index = ((runner - 1) * per_runner + _MADE[0] % per_runner) % config["envs"]
    _MADE[0] += 1
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)  # stop_process waits for its children (Ray may ignore SIGCHLD)
    log_dir = Path(tempfile.mkdtemp(prefix=f"robot_rl-rllib-runner{runner}-env{index}-", dir=config["log_root"]))
    seed = worker_seeds(config["seed"], config["envs"])[index]
    env, sim = worker_env(index, WorkerRecipe(recipe.task, recipe.params, recipe.backend, seed,
                                              recipe.ros_timeout, log_dir, False, None, {}))
    return EpisodeTap(env, runner, config["reward_scale"], sim, log_dir, index)


def take_episodes(_runner: Any = None) -> list[dict[str, Any]]:
    """On a runner: the episodes ended since the last call (and forget them)."""
    taken = list(_ENDED)
    _ENDED.clear()
    return taken


def in_order(batches: list[list[dict[str, Any]]]) -> list[EndedEpisode]:
    """The runners' ended episodes in the order episodes.csv gets them: by runner, each runner's as they ended."""
    episodes = [EndedEpisode(**episode) for batch in batches for episode in batch]
    return sorted(episodes, key=lambda e: e.runner)  # stable: each runner's keep their order


def _process_token() -> str:
    """The token this process's Ray driver uses: the one it was given already (Ray reads it once), else TOKEN."""
    given = os.environ.get("RAY_AUTH_TOKEN_PATH")
    try:
        return Path(given).read_text().strip() if given else TOKEN
    except OSError:
        return TOKEN


def _private_temp_dir() -> Path:
    """A private temp folder (0700) for a local Ray, with its token (0600), which this process's environment names
    (before ray is imported: Ray reads RAY_AUTH_MODE then)."""
    temp_dir = ray_cluster.new_temp_dir()
    token = ray_cluster.token_path(temp_dir)
    descriptor = os.open(token, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(descriptor, "w") as file:
        file.write(_process_token())
    os.environ.update(ray_cluster.ray_environment(token, {}))
    return temp_dir


def _start_local_ray(temp_dir: Path, cpus: int) -> None:
    """Ray on this machine, on loopback, in `temp_dir` (_private_temp_dir; close() removes it). The process's SIGTERM
    and SIGINT handlers are put back after ray.init, which replaces them (its core worker's SIGTERM handler aborts
    the process: a training node would die with no checkpoint instead of stopping)."""
    handlers = {signum: signal.getsignal(signum) for signum in (signal.SIGTERM, signal.SIGINT)} \
        if threading.current_thread() is threading.main_thread() else {}
    try:
        import ray
        ray.init(address="local", num_cpus=cpus, include_dashboard=False, _temp_dir=str(ray_cluster.ray_dir(temp_dir)),
                 _node_ip_address="127.0.0.1", object_store_memory=ray_cluster.OBJECT_STORE_BYTES,
                 log_to_driver=False, logging_level=logging.ERROR)
        ray_cluster.make_private(temp_dir)
    except BaseException:
        shutil.rmtree(temp_dir, ignore_errors=True)
        raise
    finally:
        for signum, handler in handlers.items():
            if handler is not None:
                signal.signal(signum, handler)


class RllibEnvs:
    """N envs of `task` for RLlib's env runners, and the Ray they run on (see the module docstring)."""

    def __init__(self, task: TaskSpec[Any], n: int, backend: str = "direct", seed: int = 0,
                 params: TaskParams | None = None, ros_timeout: float = 10.0, cluster: str | None = None):
        check_workers(n, backend)
        self.task, self.num_envs, self.backend, self.seed, self.cluster = task, n, backend, seed, cluster or ""
        self.params = params if params is not None else task.default_params()
        probe = make_env(task, params=self.params, backend="direct")
        self.single_observation_space, self.single_action_space = probe.observation_space, probe.action_space
        probe.close()
        self.observation_space, self.action_space = self.single_observation_space, self.single_action_space
        self.recipe = WorkerRecipe(task, self.params, backend, seed, ros_timeout, Path(tempfile.gettempdir()), False,
                                   None, {})
        self.worker_info: list[dict[str, Any]] = []  # the training node's log of Ray actors: the runners say theirs
        self.workers = self
        self.algorithm: Any = None
        self.closed = False
        self.abandoned = False  # an update under way was abandoned: close() ends the runners without waiting on them
        self._temp_dir: Path | None = None
        self._connected = False
        ray_cluster.prepare_driver()  # before ray is imported
        if "ray" in sys.modules and sys.modules["ray"].is_initialized():
            return  # a driver already (a test's cluster, a sweep's trial)
        if self.cluster:
            ray_cluster.connect(self.cluster)
        else:
            self._temp_dir = _private_temp_dir()
            _start_local_ray(self._temp_dir, n)
        self._connected = True

    def env_config(self, reward_scale: float, envs_per_runner: int = 1) -> dict[str, Any]:
        """What every runner's env creator gets (make_runner_env)."""
        return {"recipe": self.recipe, "seed": self.seed, "envs": self.num_envs, "envs_per_runner": envs_per_runner,
                "reward_scale": reward_scale, "log_root": None if self._temp_dir is None else str(self._temp_dir)}

    def register(self) -> str:
        """Register the runners' env creator with Ray Tune; returns its name."""
        from ray import tune
        tune.register_env(ENV_NAME, make_runner_env)
        return ENV_NAME

    def attach(self, algorithm: Any) -> None:
        """The algorithm whose runners hold these envs: close() stops it."""
        self.algorithm = algorithm

    def abandon(self) -> None:
        """An update is under way and will not be waited for (a stop): close() skips the algorithm's stop, which
        would wait on the runners' calls, and ends Ray and the runners at once."""
        self.abandoned = True

    def take_episodes(self) -> list[EndedEpisode]:
        """Every episode the healthy runners ended since the last call, in order (in_order)."""
        runners = self.algorithm.env_runner_group
        return in_order(runners.foreach_env_runner(take_episodes, local_env_runner=False))

    def runner_info(self) -> list[tuple[int, str, int]]:
        """(runner, node address, pid) of every healthy runner."""
        def where(runner: Any) -> tuple[int, str, int]:
            import ray
            return runner.worker_index, ray.util.get_node_ip_address(), os.getpid()
        return sorted(self.algorithm.env_runner_group.foreach_env_runner(where, local_env_runner=False))

    def close(self) -> None:
        """Stop the algorithm (its runners, their envs and sims), then the Ray this started (idempotent)."""
        if self.closed:
            return
        self.closed = True
        import ray
        pids: list[int] = []
        try:
            if self.algorithm is not None and not self.abandoned:
                if self._temp_dir is not None:  # the runners are processes of this machine's Ray, started here
                    pids = [pid for _, _, pid in self.runner_info()]
                self.algorithm.stop()
        finally:
            if self._connected and ray.is_initialized():
                ray.shutdown()
            _end_processes(pids)
            if self._temp_dir is not None:
                shutil.rmtree(self._temp_dir, ignore_errors=True)


def _end_processes(pids: list[int], timeout: float = RUNNER_EXIT_TIMEOUT) -> None:
    """Wait (bounded) for the runners of the Ray this process started to end, as they do once their raylet is gone
    (each ends its env's master and sim node by their death signal); SIGKILL those still there after `timeout`."""
    deadline = time.monotonic() + timeout
    while pids and time.monotonic() < deadline:
        pids = [pid for pid in pids if Path(f"/proc/{pid}").exists()]
        if pids:
            time.sleep(0.05)
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


def make_rllib_envs(task: TaskSpec[Any], n: int, backend: str, seed: int, params: TaskParams,
                    ros_timeout: float = 10.0, cluster: str | None = None) -> RllibEnvs:
    """The agent registry's vector_env of agent rllib_ppo."""
    return RllibEnvs(task, n, backend=backend, seed=seed, params=params, ros_timeout=ros_timeout, cluster=cluster)
