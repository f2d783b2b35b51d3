"""Processes run against a private ROS master: a rosmaster on a free loopback port, and every process
started here ended by its PID (process group) on close(), then every process still talking to that
master (roslaunch starts its nodes in sessions of their own) found by its environment and killed.
Used by the integration tests and the benchmark, which must leave nothing running."""
from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import rosgraph

from robot_rl import default_sigint, free_port, stop_process
from workspace_tools.launch_reaper import processes_with

T = TypeVar("T")



def alive(pid: int) -> bool:
    """Whether process `pid` runs (a zombie, ended but not yet reaped, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def group_members(pgid: int) -> list[int]:
    """The live processes of process group `pgid`."""
    members = []
    for entry in os.listdir("/proc"):
        try:
            fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, ValueError, IndexError):
            continue
        if entry.isdigit() and int(fields[2]) == pgid and fields[0] != "Z":
            members.append(int(entry))
    return members

def processes_using(uri: str) -> list[int]:
    """Pids of the processes (other than this one) whose environment points ROS_MASTER_URI at `uri`."""
    return processes_with("ROS_MASTER_URI", uri)


def stop(process: subprocess.Popen, timeout: float = 10.0) -> None:
    """End a process group we started: SIGINT (roslaunch shuts its nodes down), then SIGKILL after `timeout` s,
    with a RuntimeWarning naming it."""
    stop_process(process, timeout, group=True)


class Processes:
    """Processes started for one test, with one environment; close() ends them all by PID."""

    def __init__(self, log_dir: Path, cwd: Path | None = None, **env: str):
        self.env = dict(os.environ, ROS_LOG_DIR=str(log_dir), ROS_HOME=str(log_dir), **env)
        self.cwd = cwd
        self._processes: list[subprocess.Popen] = []

    def start(self, command: list[str], **kwargs) -> subprocess.Popen:
        """Start `command` in a process group of its own, with SIGINT's default action whatever this process
        has (pytest started as a background job ignores SIGINT): close()'s SIGINT ends it."""
        process = subprocess.Popen(command, env=self.env, cwd=self.cwd, start_new_session=True,
                                   preexec_fn=default_sigint, **kwargs)
        self._processes.append(process)
        return process

    def run(self, command: list[str], timeout: float) -> subprocess.CompletedProcess:
        """Run a command to completion (bounded), capturing its output."""
        process = self.start(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            stdout, stderr = process.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            stop(process)
            stdout, stderr = process.communicate()
            raise AssertionError(f"{' '.join(command)} did not finish within {timeout} s\n{stdout}\n{stderr}") \
                from None
        return subprocess.CompletedProcess(command, process.returncode, stdout, stderr)

    def close(self) -> None:
        for process in reversed(self._processes):
            stop(process)


class RosMaster(Processes):
    """A rosmaster on a free loopback port; processes started here talk to it."""

    def __init__(self, log_dir: Path, cwd: Path | None = None):
        port = free_port()
        self.uri = f"http://127.0.0.1:{port}"
        super().__init__(log_dir, cwd, ROS_MASTER_URI=self.uri, ROS_HOSTNAME="127.0.0.1", ROS_IP="127.0.0.1")
        master = self.start(["rosmaster", "--core", "-p", str(port)])
        self.master_pid = master.pid
        deadline = time.monotonic() + 20.0
        while True:  # bounded poll: rosmaster has no readiness signal
            try:
                self.params.getPid()
                return
            except OSError:
                if master.poll() is not None or time.monotonic() > deadline:
                    self.close()
                    raise RuntimeError(f"rosmaster on {self.uri} did not come up within 20 s") from None
                time.sleep(0.05)

    @property
    def params(self) -> rosgraph.Master:
        return rosgraph.Master("/pytest", master_uri=self.uri)

    def leftovers(self) -> list[int]:
        """Processes other than the master still using it (after a launch ended, there should be none)."""
        return [pid for pid in processes_using(self.uri) if pid != self.master_pid]

    def close(self) -> None:
        super().close()
        for pid in processes_using(self.uri):  # orphans of a roslaunch that was killed
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def wait_for(predicate: Callable[[], T], timeout: float, what: str, interval: float = 0.02) -> T:
    """Poll `predicate` until it returns something true, and return that; AssertionError naming `what` after
    `timeout` s. For what has no notification: a file or log another process writes, the master's state."""
    end = time.monotonic() + timeout
    while not (value := predicate()):
        if time.monotonic() > end:
            raise AssertionError(f"{what} did not happen within {timeout} s")
        time.sleep(interval)
    return value


def launch_args(**args: object) -> list[str]:
    """roslaunch's `name:=value` arguments."""
    return [f"{key}:={value}" for key, value in args.items()]
