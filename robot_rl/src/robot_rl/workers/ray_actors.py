"""Env workers as Ray actors: robot_rl.workers.pipe's EnvWorkers over a Ray cluster (cluster:=ray or an address).

`RayEnvWorkers` has EnvWorkers' interface (send, receive, receive_all, request_all, close, worker_info), so
the tabular trainer from N envs, the gymnasium vector env and the SB3 VecEnv take it unchanged. Actor i is
one env, as pipe worker i is: it makes its env with the same i-th seed (worker_seeds), over ROS on a private
master and sim node (robot_rl.workers.private_sim) on its own node's loopback, and answers the same commands with
the same replies (robot_rl.workers.base.answer); the driver takes them in the same order, so a run repeats and
equals the same run over pipe workers. The actors are spread over the cluster's nodes (Ray's SPREAD), one
CPU each; each is a process of its own whose methods run on its main thread (a sync actor), which matters:
its master and sim node get SIGTERM when that thread ends (PR_SET_PDEATHSIG). Unlike pipe workers, they run
in the normal scheduling class: Ray's threads hand each call to the main thread, and a SCHED_BATCH main thread
waits for its turn at every hand-over (Ray actors at N = 2 reached 0.44-0.47x of pipe workers' env steps/s with it,
0.65-0.69x without, on a loaded 2-core machine). Each step is a plain actor call: a Ray Compiled Graph over the
actors was no faster within one node and 5-10x slower to an actor on another node, nor were threaded or async actors
faster (workspace_tools/scripts/ray_call_bench.py; docs/research/2026-11-26-ray-actors.md). Each call costs about as
much CPU as the env step it carries (0.85-1.05 ms on a 2-core machine), so on one machine Ray actors stay well below
pipe workers whatever the scheduling: they are for envs spread over machines.

An actor's logs (its master's and sim node's, the traceback of a failure) stay on its node, in a temporary folder
the errors name with the node's address; close() removes them unless a worker failed. Every wait is bounded
(ray.wait with a timeout; ray.get(timeout=...) costs a quarter millisecond more per call) and made of waits of at
most WAIT_SLICE s, between which a stop request (robot_rl.workers.base.stop_waits_when: the training node's SIGTERM
or SIGINT) ends it with WorkersStopped: the node's signal handler only records the stop, so a stop during an actor's
start (up to start_timeout) or a reply (up to ros_timeout + 30 s) would otherwise wait for its end. The actors are
not detached: they end with this driver, and close() ends them (each stops its sim node and master, then ray.kill;
after a stop, those that owe no reply get STOP_CLOSE_TIMEOUT s to close, and every actor is then killed, its master
and sim node ending by their death signal). A node that is lost takes its actors with it: each exits once it finds
its raylet gone, and its master and sim node end by their death signal. Ray restarts a lost actor on a node with a
free CPU (up to max_restarts times): its constructor makes a new env with the same seed, which is reset, and the
reply owed becomes a WorkerRestarted with that reset's observation. The tabular trainer from N envs starts that
env's episode under way anew (robot_rl.agents.qlearn.vector_trainer); the gymnasium and SB3 faces end with it as
with any WorkerError (resume:=true continues the run). With no restart left, or none placed within start_timeout, a
lost actor is a WorkerError naming the env and its node.
"""
from __future__ import annotations

import os
import shutil
import signal
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import ray
from ray.exceptions import ActorUnavailableError, GetTimeoutError, RayActorError, RayTaskError

from ..envs.backends.factory import over_ros
from ..params import TaskParams
from ..task import TaskSpec
from .base import (
    CLOSE_TIMEOUT,
    REPLY_MARGIN,
    START_TIMEOUT,
    WorkerError,
    WorkerRecipe,
    WorkerRestarted,
    WorkersStopped,
    answer,
    check_workers,
    stop_requested,
    worker_env,
    worker_seeds,
)
from .cluster import connect
from .pipe import EnvWorkers

RESTART_POLL = 0.5  # s between asks whether a lost actor is back
WAIT_SLICE = 0.5  # s at most of one ray.wait: a stop request ends a wait within this
STOP_CLOSE_TIMEOUT = 3.0  # s for the actors to close after a stop, before they are killed


class EnvActor:
    """One env on one Ray worker process (declared remote below)."""

    def __init__(self, index: int, recipe: WorkerRecipe):
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)  # stop_process waits for its children (Ray may ignore SIGCHLD)
        self.log_dir = Path(tempfile.mkdtemp(prefix=f"robot_rl-ray-worker{index}-"))
        self.index = index
        self.env, self.sim = worker_env(index, replace(recipe, log_dir=self.log_dir))

    def describe(self) -> tuple[Any, Any, dict[str, Any], dict[str, Any]]:
        """Its spaces, metadata and (as a pipe worker's) its pid, master URI and children, plus its node."""
        context = ray.get_runtime_context()
        sim = self.sim
        info = {"pid": os.getpid(), "master_uri": sim.uri if sim else None,
                "children": [p.pid for p in sim.processes] if sim else [], "node_id": context.get_node_id(),
                "node_ip": ray.util.get_node_ip_address(), "log_dir": str(self.log_dir / f"worker{self.index}")}
        return self.env.observation_space, self.env.action_space, self.env.metadata, info

    def command(self, command: str, data: Any) -> Any:
        return answer(self.env, command, data)

    def close(self, keep_logs: bool) -> None:
        """End its env, its sim node and its master; remove its logs unless asked to keep them."""
        try:
            self.env.close()
        except Exception:  # the sim may already be gone; its processes end below
            pass
        if self.sim is not None:
            import rospy
            rospy.signal_shutdown("the vector env closes this worker")  # unregisters while the master is up
            self.sim.close()
        if not keep_logs:
            shutil.rmtree(self.log_dir, ignore_errors=True)


RemoteEnvActor = ray.remote(EnvActor)  # sync, one call at a time (Ray's default): methods on the main thread


class RayEnvWorkers(EnvWorkers):
    """N Ray actors, each with one env of `task` (see the module docstring); EnvWorkers' arguments, plus the
    cluster ("ray" or an address: robot_rl.workers.cluster.connect; ignored when this process is a driver already) and
    how many times Ray may restart a lost actor (max_restarts; 0: a lost actor is a WorkerError)."""

    def __init__(self, task: TaskSpec[Any], n: int, backend: str = "ros", seed: int | None = 0,
                 params: TaskParams | None = None, ros_timeout: float = 10.0, start_timeout: float = START_TIMEOUT,
                 max_episode_steps: int | None = None, log_dir: Path | None = None, cluster: str = "ray",
                 max_restarts: int = 1, **env_kwargs: Any):
        check_workers(n, backend)
        self.task, self.n, self.backend = task, n, backend
        self.params = params if params is not None else task.default_params()
        self.seeds = worker_seeds(seed, n)
        self.reply_timeout = ros_timeout + REPLY_MARGIN
        self.start_timeout, self.max_restarts = start_timeout, max_restarts
        self._own_log_dir = False  # each actor keeps its logs on its node
        self.log_dir = Path(log_dir) if log_dir is not None else Path(tempfile.gettempdir())
        self._pending = [False] * n
        self.closed = False
        self.failed = False
        self._connected = False
        self._stopped_at: float | None = None  # when a stop request was first seen
        self._actors: list[Any] = []
        self._refs: list[Any] = [None] * n
        self.worker_info: list[dict[str, Any]] = [{} for _ in range(n)]
        with self._starting(start_timeout):
            if not ray.is_initialized():
                connect(cluster)
                self._connected = True
            for i in range(n):
                recipe = WorkerRecipe(task, self.params, backend, self.seeds[i], ros_timeout, self.log_dir, False,
                                      max_episode_steps, env_kwargs)
                placed = RemoteEnvActor.options(num_cpus=1, max_restarts=max_restarts, scheduling_strategy="SPREAD")
                self._actors.append(placed.remote(i, recipe))
            for i, actor in enumerate(self._actors):
                self._refs[i] = actor.describe.remote()
                self._pending[i] = True

    def _where(self, i: int) -> str:
        info = self.worker_info[i]
        return f"on node {info['node_ip']} ({info['node_id'][:8]})" if info else "(not started)"

    def _what_to_check(self, i: int) -> str:
        info = self.worker_info[i]
        if not info:
            return "its node's Ray logs say more (./ws cluster status names the nodes)"
        logs = "its master's and sim node's logs" if over_ros(self.backend) else "its logs"
        return f"{logs} are kept on node {info['node_ip']} in {info['log_dir']}"

    def _wait(self, refs: list[Any], timeout: float, what: str) -> list[Any]:
        """The refs that are ready within `timeout` (all, or fewer when it ran out), in waits of WAIT_SLICE s at
        most; WorkersStopped (naming `what`) once stop_requested() says stop."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            ready, _ = ray.wait(refs, num_returns=len(refs), timeout=max(0.0, min(WAIT_SLICE, left)), fetch_local=True)
            if len(ready) == len(refs) or left <= WAIT_SLICE:
                return ready
            if stop_requested():
                self._stopped_at = self._stopped_at or time.monotonic()
                raise WorkersStopped(f"stopped while waiting for {what} (a stop request: SIGTERM or SIGINT)")

    def _close_wait(self, refs: list[Any], timeout: float) -> None:
        """Wait for `refs` at most `timeout`, and no longer than STOP_CLOSE_TIMEOUT after a stop request."""
        deadline = time.monotonic() + timeout
        while True:
            if self._stopped_at is None and stop_requested():
                self._stopped_at = time.monotonic()
            if self._stopped_at is not None:
                deadline = min(deadline, self._stopped_at + STOP_CLOSE_TIMEOUT)
            left = deadline - time.monotonic()
            if left <= 0 or len(ray.wait(refs, num_returns=len(refs), timeout=min(WAIT_SLICE, left))[0]) == len(refs):
                return

    def send(self, i: int, command: str, data: Any = None) -> None:
        if self.closed:
            raise WorkerError("the vector env is closed")
        self._refs[i] = self._actors[i].command.remote(command, data)
        self._pending[i] = True

    def receive(self, i: int, timeout: float | None = None, what: str = "reply") -> Any:
        """Actor i's reply (bounded); WorkerError if it failed, was lost or did not answer."""
        timeout = self.reply_timeout if timeout is None else timeout
        try:
            # ray.wait, then ray.get: a quarter millisecond less per call than ray.get(timeout=...) (Ray 2.60)
            if not self._wait([self._refs[i]], timeout, f"worker {i}'s {what} (ray, {self._where(i)})"):
                raise GetTimeoutError
            reply = ray.get(self._refs[i])
        except GetTimeoutError:
            raise self._failure(f"worker {i} (ray, {self._where(i)}) did not {what} within {timeout:.0f} s (is the "
                                f"machine overloaded, or the sim frozen?); {self._what_to_check(i)}") from None
        except RayActorError as error:
            self._pending[i] = False
            if self.max_restarts > 0:
                raise self._restarted(i, what, error) from None
            raise self._failure(f"worker {i} (ray, {self._where(i)}) was lost before its {what} (its process or "
                                f"its node died: {' '.join(str(error).split())[:200]}); "
                                f"{self._what_to_check(i)}") from None
        except RayTaskError as error:
            self._pending[i] = False
            cause = error.cause if error.cause is not None else error
            raise self._failure(f"worker {i} (ray, {self._where(i)}) failed: {type(cause).__name__}: "
                                f"{' '.join(str(cause).split())}; {self._what_to_check(i)}") from None
        self._pending[i] = False
        self._refs[i] = None
        return reply

    def _restarted(self, i: int, what: str, error: RayActorError) -> WorkerError:
        """After actor i was lost: WorkerRestarted once Ray has restarted it (its constructor made a new env, on
        another node if its own is gone) and it has reset with its seed; else the loss as a WorkerError."""
        lost = f"worker {i} (ray, {self._where(i)}) was lost before its {what}"
        deadline = time.monotonic() + self.start_timeout
        try:
            while True:  # until Ray has found the node dead and restarted the actor elsewhere (bounded)
                self._refs[i] = self._actors[i].describe.remote()
                try:
                    if not self._wait([self._refs[i]], max(0.0, deadline - time.monotonic()), f"worker {i}'s restart"):
                        raise GetTimeoutError
                    info = ray.get(self._refs[i])[3]
                    break
                except ActorUnavailableError:  # not yet known dead, or restarting
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(RESTART_POLL)
            self._refs[i] = self._actors[i].command.remote("reset", (self.seeds[i], None))
            if not self._wait([self._refs[i]], self.reply_timeout, f"worker {i}'s reset after its restart"):
                raise GetTimeoutError
            observation, reset_info = ray.get(self._refs[i])
        except (RayActorError, RayTaskError, GetTimeoutError) as again:
            return self._failure(f"{lost}, and Ray could not restart it within {self.start_timeout:.0f} s ("
                                 f"{type(again).__name__}; is there a node with a free CPU?): "
                                 f"{' '.join(str(error).split())[:200]}")
        self._refs[i] = None
        self.worker_info[i] = info
        return WorkerRestarted(f"{lost}; restarted {self._where(i)}, its master {info['master_uri']}", i,
                               observation, reset_info)

    def receive_all(self, timeout: float | None = None, what: str = "reply") -> list[Any]:
        """Every actor's reply within `timeout` for all of them; the first failure is raised after every other
        reply has been read. The failure, or a reply late, is each actor's receive()'s."""
        timeout = self.reply_timeout if timeout is None else timeout
        deadline = time.monotonic() + timeout
        if all(ref is not None for ref in self._refs):  # the usual case, in one wait: every reply arrives
            ready = self._wait(self._refs, timeout, f"the {what} of the {self.n} ray workers")
            if len(ready) == self.n:
                try:
                    replies = ray.get(self._refs)
                except (RayActorError, RayTaskError):
                    pass  # each actor's own reply below names the failure
                else:
                    self._pending = [False] * self.n
                    self._refs = [None] * self.n
                    return replies
        replies = [None] * self.n
        failure: WorkerError | None = None
        for i in range(self.n):
            try:
                replies[i] = self.receive(i, max(0.0, deadline - time.monotonic()), what)
            except WorkerError as error:
                failure = failure or error
        if failure is not None:
            raise failure
        return replies

    def close(self) -> None:
        """End every actor and what it started (bounded, and within STOP_CLOSE_TIMEOUT after a stop; idempotent);
        disconnect if this made the connection."""
        if self.closed:
            return
        self.closed = True
        if not ray.is_initialized():  # disconnected already: the actors ended with the connection
            return
        owed = [ref for i, ref in enumerate(self._refs) if self._pending[i] and ref is not None]
        if owed and self._stopped_at is None:  # the replies owed, e.g. after an interrupted step; a stop's are not
            self._close_wait(owed, CLOSE_TIMEOUT)
        closing = [actor.close.remote(self.failed) for actor in self._actors]  # a busy actor's waits its turn
        if closing:
            self._close_wait(closing, CLOSE_TIMEOUT)
        for actor in self._actors:
            ray.kill(actor, no_restart=True)
        if self._connected:
            ray.shutdown()
