"""Env workers as processes on this machine, one per env, each answering its parent over a pipe.

`EnvWorkers` starts N worker processes (multiprocessing's "spawn": rospy's state must never cross a
fork), over ROS (each with a master and a sim of its own) or direct; what worker i makes and answers is
robot_rl.workers.base's.

Every wait is bounded: a worker that does not start within `start_timeout`, or does not answer a
step within `ros_timeout` plus a margin, ends the vector env with a WorkerError naming the worker and
what to check. close() ends every worker and everything it started: it asks each to close (a worker
stops its sim node and master by PID), then SIGTERM, then SIGKILL, each bounded. After an exception
in a worker the error names it and the others go on until close(). Workers ignore SIGINT: Ctrl-C in
a terminal reaches the whole process group (the masters and sim nodes end at once), and the parent
ends the workers through close(). Each worker and each process it starts gets SIGTERM from the kernel
when its parent dies (PR_SET_PDEATHSIG), and a worker ends when its pipe to the parent closes.

Workers run in Linux's SCHED_BATCH class, and so does every process they start (`run_as_batch`): the
parent wakes the workers one after another, and a normal worker woken on the parent's CPU preempts the
parent before it has woken the next worker, which then starts late.

Two faces over the same workers: `robot_rl.workers.vector_env.RobotVectorEnv` is a gymnasium VectorEnv,
`robot_rl.agents.sb3.vec_env.RobotVecEnv` a Stable-Baselines3 VecEnv.
"""
from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import os
import select
import shutil
import signal
import tempfile
import time
import traceback
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from multiprocessing import resource_tracker
from pathlib import Path
from typing import Any

from ..envs.backends.factory import over_ros
from ..params import TaskParams
from ..task import TaskSpec
from .base import (
    CLOSE_TIMEOUT,
    REPLY_MARGIN,
    START_TIMEOUT,
    WorkerError,
    WorkerRecipe,
    answer,
    check_workers,
    worker_env,
    worker_seeds,
)
from .private_sim import set_pdeathsig

PARENT_EXIT_WAIT = 2.0  # s a worker signalled to end waits for its parent's end of the pipe to close


def run_as_batch() -> None:
    """Put this process, and the processes it starts from now on, in Linux's SCHED_BATCH scheduling class:
    their wake-ups never preempt the running task, so a parent that wakes N workers in turn is not
    interrupted by the first before it has woken the others (no privilege needed; where the system refuses,
    e.g. a seccomp filter, the process keeps its class)."""
    try:
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    except (AttributeError, OSError):  # not Linux, or not allowed here
        pass


@contextmanager
def _workers_born_blocking_sigint() -> Iterator[None]:
    """Processes started in the block are born with SIGINT blocked (spawn's fork and exec keep the signal mask),
    so that a Ctrl-C while a worker imports waits, pending, until the worker ignores SIGINT and discards it:
    it cannot end the worker with a traceback. Only the calling thread blocks SIGINT meanwhile, and this process
    keeps its handler: a SIGINT sent to it then is handled by another thread or when the block ends (before, the
    block also set SIG_IGN, process-wide, and a SIGINT that reached one of rospy's threads then was lost).
    multiprocessing's resource tracker is started first: starting it unblocks SIGINT (bpo-33613's mask)."""
    resource_tracker.ensure_running()
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def _raise_system_exit(_signum: int, _frame: Any) -> None:
    raise SystemExit(1)


def _parent_died(conn: multiprocessing.connection.Connection, parent: int) -> bool:
    """Whether the worker's parent has died. Its end of the pipe closes as it dies; the kernel may send
    the worker its death signal before then, and, when the parent had threads, before it reparents the
    worker (the thread that started it died first), so wait a moment for the pipe to say so."""
    if os.getppid() != parent:
        return True
    try:
        if conn.poll(PARENT_EXIT_WAIT):
            conn.recv()
    except (EOFError, OSError):
        return True
    return os.getppid() != parent


def _worker(index: int, recipe: WorkerRecipe, conn: multiprocessing.connection.Connection) -> None:
    """A worker's life: make the env, then answer one reply per command until "close" or the pipe closes."""
    parent = os.getppid()
    set_pdeathsig(signal.SIGTERM)
    run_as_batch()  # before its master and sim node start: they inherit it
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # then a Ctrl-C pending since its birth is discarded
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # (_workers_born_blocking_sigint)
    signal.signal(signal.SIGTERM, _raise_system_exit)  # ends the worker through the finally below
    env, sim = None, None
    parent_gone, closing = False, False  # whether the pipe closed without a "close"; whether "close" came
    try:
        env, sim = worker_env(index, recipe)
        info = {"pid": os.getpid(), "master_uri": sim.uri if sim else None,
                "children": [p.pid for p in sim.processes] if sim else []}
        conn.send(("ok", (env.observation_space, env.action_space, env.metadata, info)))
        while True:
            try:
                command, data = conn.recv()
            except EOFError:  # the parent is gone
                parent_gone = True
                break
            if command == "close":
                closing = True
                conn.send(("ok", None))
                break
            conn.send(("ok", answer(env, command, data)))
    except (KeyboardInterrupt, SystemExit):
        pass
    except BaseException as error:  # the parent re-raises it in one line, naming the worker and its logs
        folder = recipe.log_dir / f"worker{index}"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "traceback.txt").write_text(traceback.format_exc())
        try:
            conn.send(("error", f"{type(error).__name__}: {' '.join(str(error).split())}"))
        except OSError:
            pass
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)  # a later SIGTERM must not cut the clean-up short
        orphaned = parent_gone or (not closing and _parent_died(conn, parent))
        try:
            if env is not None:
                env.close()
        except Exception:  # the sim may already be gone; its processes end below
            pass
        if sim is not None:
            import rospy
            rospy.signal_shutdown("the vector env closes this worker")  # unregisters while the master is up
            sim.close()
        conn.close()
        if recipe.own_log_dir and orphaned:  # nobody else will remove the parent's temporary folder
            shutil.rmtree(recipe.log_dir / f"worker{index}", ignore_errors=True)
            try:
                os.rmdir(recipe.log_dir)  # the last worker out removes the folder
            except OSError:
                pass


class EnvWorkers:
    """N worker processes, each with one env of `task` (see the module docstring)."""

    def __init__(self, task: TaskSpec[Any], n: int, backend: str = "ros", seed: int | None = 0,
                 params: TaskParams | None = None, ros_timeout: float = 10.0, start_timeout: float = START_TIMEOUT,
                 max_episode_steps: int | None = None, log_dir: Path | None = None, **env_kwargs: Any):
        check_workers(n, backend)
        self.task, self.n, self.backend = task, n, backend
        self.params = params if params is not None else task.default_params()
        self.seeds = worker_seeds(seed, n)
        self.reply_timeout = ros_timeout + REPLY_MARGIN
        self._own_log_dir = log_dir is None
        self.log_dir = Path(tempfile.mkdtemp(prefix="robot_rl-workers-")) if log_dir is None else Path(log_dir)
        self._pending = [False] * n  # whether worker i owes a reply
        self._conns: list[multiprocessing.connection.Connection] = []
        self._pollers: list[select.poll] = []  # one per worker's pipe: receive() waits on it (bounded)
        self._processes: list[multiprocessing.process.BaseProcess] = []
        self.closed = False
        self.failed = False  # a worker failed: close() keeps its logs where the error said they are
        context = multiprocessing.get_context("spawn")
        with self._starting(start_timeout):
            for i in range(n):
                recipe = WorkerRecipe(task, self.params, backend, self.seeds[i], ros_timeout, self.log_dir,
                                      self._own_log_dir, max_episode_steps, env_kwargs)
                parent, child = context.Pipe()
                process = context.Process(target=_worker, args=(i, recipe, child), name=f"robot_rl-worker{i}",
                                          daemon=True)
                with _workers_born_blocking_sigint():
                    process.start()
                child.close()
                self._conns.append(parent)
                self._pollers.append(select.poll())
                self._pollers[i].register(parent.fileno(), select.POLLIN)
                self._processes.append(process)
                self._pending[i] = True

    @contextmanager
    def _starting(self, start_timeout: float) -> Iterator[None]:
        """Around starting the workers, each of which then owes its first reply: wait for those replies (bounded)
        and take the env's spaces and each worker's info from them; on any failure, close what started."""
        try:
            yield
            ready = self.receive_all(start_timeout, "start")
        except BaseException:
            self.close()
            raise
        self.observation_space, self.action_space, self.metadata = ready[0][:3]
        # Per worker: its pid, its master's URI (None when direct) and the pids of its master and sim node
        # (Ray actors: also their node).
        self.worker_info: list[dict[str, Any]] = [reply[3] for reply in ready]

    def _failure(self, message: str) -> WorkerError:
        """The error to raise; close() then keeps the workers' logs, which the message names."""
        self.failed = True
        return WorkerError(message, self.log_dir if self._own_log_dir else None)

    def _what_to_check(self, i: int) -> str:
        logs = "its traceback, master's and sim node's logs" if over_ros(self.backend) else "its traceback"
        return f"{logs} (if any) are kept in {self.log_dir / f'worker{i}'}"

    def send(self, i: int, command: str, data: Any = None) -> None:
        if self.closed:
            raise WorkerError("the vector env is closed")
        try:
            self._conns[i].send((command, data))
        except OSError as error:
            raise self._failure(f"worker {i} ({self.backend}) is gone ({error}); {self._what_to_check(i)}") from None
        self._pending[i] = True

    def receive(self, i: int, timeout: float | None = None, what: str = "reply") -> Any:
        """Worker i's reply (bounded); WorkerError if it failed, died or did not answer."""
        timeout = self.reply_timeout if timeout is None else timeout
        if not self._pollers[i].poll(timeout * 1000.0):  # readable, or closed (then _read names the death)
            raise self._late(i, timeout, what)
        return self._read(i, what)

    def _read(self, i: int, what: str) -> Any:
        """Worker i's reply, which has arrived."""
        try:
            status, data = self._conns[i].recv()
        except (EOFError, OSError):
            raise self._died(i, what) from None
        self._pending[i] = False
        if status == "error":
            raise self._failure(f"worker {i} ({self.backend}) failed: {data}; {self._what_to_check(i)}")
        return data

    def _late(self, i: int, timeout: float, what: str) -> WorkerError:
        return self._failure(f"worker {i} ({self.backend}, pid {self._processes[i].pid}) did not {what} within "
                           f"{timeout:.0f} s (is the machine overloaded, or the sim frozen?); {self._what_to_check(i)}")

    def _died(self, i: int, what: str) -> WorkerError:
        self._processes[i].join(1.0)
        return self._failure(f"worker {i} ({self.backend}) died (exit code {self._processes[i].exitcode}) before "
                             f"its {what}; {self._what_to_check(i)}")

    def receive_all(self, timeout: float | None = None, what: str = "reply") -> list[Any]:
        """Every worker's reply, read in the order they arrive, within `timeout` for all of them; the first
        failure is raised after every other reply has been read (a reply still owed at the deadline stays
        owed: receive() or close() reads it)."""
        timeout = self.reply_timeout if timeout is None else timeout
        deadline = time.monotonic() + timeout
        replies: list[Any] = [None] * self.n
        failure: WorkerError | None = None
        waiting = {self._conns[i].fileno(): i for i in range(self.n)}
        poller = select.poll()
        for fd in waiting:
            poller.register(fd, select.POLLIN)
        while waiting:
            ready = poller.poll(max(0.0, deadline - time.monotonic()) * 1000.0)
            if not ready:  # the first worker still owed names the wait
                failure = failure or self._late(min(waiting.values()), timeout, what)
                break
            for fd, _ in ready:
                i = waiting.pop(fd)
                poller.unregister(fd)
                try:
                    replies[i] = self._read(i, what)
                except WorkerError as error:
                    failure = failure or error
        if failure is not None:
            raise failure
        return replies

    def request_all(self, command: str, data: Sequence[Any]) -> list[Any]:
        for i, item in enumerate(data):
            self.send(i, command, item)
        return self.receive_all(what=f"answer {command!r}")

    def close(self) -> None:
        """End every worker and what it started (bounded; idempotent)."""
        if self.closed:
            return
        self.closed = True
        for i, conn in enumerate(self._conns):
            try:
                if self._pending[i] and conn.poll(CLOSE_TIMEOUT):
                    conn.recv()  # the reply owed, e.g. after an interrupted step
                conn.send(("close", None))
            except (EOFError, OSError):
                pass
        for process in self._processes:
            process.join(CLOSE_TIMEOUT)
            for stop in (process.terminate, process.kill):
                if process.exitcode is None:
                    stop()
                    process.join(CLOSE_TIMEOUT)
        for conn in self._conns:
            conn.close()
        if self._own_log_dir and not self.failed:
            shutil.rmtree(self.log_dir, ignore_errors=True)

    def __del__(self) -> None:
        if not getattr(self, "closed", True):
            self.close()


