"""A robot's sim on a ROS master of its own: what each worker of a vector env over ROS runs.

`PrivateSim` starts `rosmaster --core` on a free loopback port, sets the sim's parameters on it (the
robot's URDF, its sim config, paused, the noise seed, /use_sim_time) and starts the sim node directly
(no roslaunch, no rosout), then waits, bounded, until its services answer. Every topic keeps the
tutorials' global name, because nothing else talks to that master (as multiros and rocket_league
run one master per env). close() ends both processes by PID (SIGINT, then SIGKILL); each child also
gets SIGTERM from the kernel if the process that started it dies (PR_SET_PDEATHSIG), so nothing
outlives it. `uri` is the master's URI: point ROS_MASTER_URI at it before this process becomes a node.
"""
from __future__ import annotations

import ctypes
import os
import signal
import socket
import subprocess
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import yaml

from ..task import RobotSpec

PR_SET_PDEATHSIG = 1
STOP_TIMEOUT = 5.0  # s each process gets to end after SIGINT before SIGKILL


class PrivateSimError(RuntimeError):
    """The private master or sim node did not start; the message says which and shows its log."""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def set_pdeathsig(sig: int = signal.SIGTERM) -> None:
    """Ask the kernel to send this process `sig` when its parent dies (a safety net beside close())."""
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, sig)


def default_sigint() -> None:
    """In a child before exec (preexec_fn): SIGINT's default action and no signal blocked, so that the SIGINT
    stop_process sends ends it. An ignored signal stays ignored across exec, a blocked one stays blocked: a
    vector env's worker ignores SIGINT, a Ray worker blocks some signals, and bash starts a background job of a
    non-interactive shell (`./ws test ... &` in a script) with SIGINT ignored; a rosmaster started from any of
    them ignored SIGINT until stop_process's SIGKILL, `timeout` s later."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_SETMASK, set())


def prepare_child() -> None:
    """In a child before exec (preexec_fn): SIGTERM when its parent dies, and default_sigint()."""
    set_pdeathsig()
    default_sigint()


def _sigint_refused(pid: int) -> str:
    """" (it ignores SIGINT)" or " (it blocks SIGINT)" when /proc says so of `pid`, else ""."""
    bit = 1 << (signal.SIGINT - 1)
    try:
        status = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines())
        return next((f" (it {verb} SIGINT)" for field, verb in (("SigIgn", "ignores"), ("SigBlk", "blocks"))
                     if int(status[field], 16) & bit), "")
    except (OSError, KeyError, ValueError):
        return ""


def stop_process(process: subprocess.Popen[Any], timeout: float = STOP_TIMEOUT, group: bool = False) -> None:
    """SIGINT (ROS nodes, roslaunch and rosmaster shut down cleanly), then SIGKILL; bounded. With `group`, to
    the process group the process leads (started with start_new_session: roslaunch and the nodes it started).
    A process still running `timeout` s after SIGINT is a fault (start it with default_sigint): it is killed,
    then a RuntimeWarning names it and, if it ignored or blocked SIGINT, says so."""
    refused: str | None = None  # set when SIGINT did not end it: why, if /proc says
    for sig in (signal.SIGINT, signal.SIGKILL):
        if process.poll() is not None:
            break
        try:
            if group:
                os.killpg(process.pid, sig)
            else:
                process.send_signal(sig)
        except ProcessLookupError:
            break
        try:
            process.wait(timeout)
            break
        except subprocess.TimeoutExpired:
            if sig == signal.SIGINT:
                refused = _sigint_refused(process.pid)
    if refused is not None:
        command = " ".join(map(str, process.args)) if isinstance(process.args, list) else str(process.args)
        end = "killed" if process.poll() is not None else f"still running {timeout} s after SIGKILL"
        warnings.warn(f"{'process group' if group else 'process'} {process.pid} ({command[:120]}) was still "
                      f"running {timeout} s after SIGINT{refused}: {end}", RuntimeWarning, stacklevel=2)


def _tail(path: Path, lines: int = 15) -> str:
    try:
        text = path.read_text(errors="replace").splitlines()
    except OSError:
        return "(no log)"
    return "\n".join(text[-lines:]) or "(empty log)"


def _sim_node_script() -> str:
    """The sim node's executable (devel or install space), found as rosrun finds it."""
    import roslib.packages
    found = roslib.packages.find_node("pybullet_sim", "sim_node.py")
    if not found:
        raise PrivateSimError("pybullet_sim's sim_node.py not found on ROS_PACKAGE_PATH; source the workspace "
                              "(./ws exec ...)")
    return found[0]


class PrivateSim:
    """rosmaster + the robot's sim node (paused), both ours; see the module docstring."""

    def __init__(self, robot: RobotSpec, log_dir: Path, seed: int = 0, timeout: float = 30.0):
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.port = free_port()
        self.uri = f"http://127.0.0.1:{self.port}"
        self.env = dict(os.environ, ROS_MASTER_URI=self.uri, ROS_HOSTNAME="127.0.0.1", ROS_IP="127.0.0.1",
                        ROS_LOG_DIR=str(self.log_dir), ROS_HOME=str(self.log_dir))
        self.processes: list[subprocess.Popen[bytes]] = []
        self._logs: list[IO[bytes]] = []
        try:
            master = self._start("rosmaster", ["rosmaster", "--core", "-p", str(self.port)])
            self._wait("the ROS master", "rosmaster", master, self._master_online, timeout)
            self._set_params(robot, seed)
            sim_node = self._start("sim_node", [sys.executable, _sim_node_script(), "__name:=pybullet_sim"])
            self._wait("the sim node", "sim_node", sim_node, self._sim_ready, timeout)
        except BaseException:
            self.close()
            raise

    def _start(self, name: str, command: list[str]) -> subprocess.Popen[bytes]:
        log = open(self.log_dir / f"{name}.log", "wb")
        self._logs.append(log)
        process = subprocess.Popen(command, env=self.env, stdin=subprocess.DEVNULL, stdout=log,
                                   stderr=subprocess.STDOUT, preexec_fn=prepare_child)
        self.processes.append(process)
        return process

    def _wait(self, what: str, name: str, process: subprocess.Popen[bytes], ready: Callable[[], bool],
              timeout: float) -> None:
        """Poll `ready` (bounded: neither process has a readiness signal) while `process` lives."""
        deadline = time.monotonic() + timeout
        log = self.log_dir / f"{name}.log"
        while not ready():
            if process.poll() is not None:
                raise PrivateSimError(f"{what} on {self.uri} exited with code {process.returncode} at start; its "
                                      f"log ({log}):\n{_tail(log)}")
            if time.monotonic() > deadline:
                raise PrivateSimError(f"{what} on {self.uri} was not ready within {timeout} s (is the machine "
                                      f"overloaded?); its log ({log}):\n{_tail(log)}")
            time.sleep(0.02)

    def _master(self) -> Any:
        import rosgraph
        return rosgraph.Master("/robot_rl_private_sim", master_uri=self.uri)

    def _master_online(self) -> bool:
        try:
            self._master().getPid()
            return True
        except OSError:
            return False

    def _sim_ready(self) -> bool:
        import rosgraph

        from pybullet_sim.names import RENDER_SERVICE
        try:
            self._master().lookupService(RENDER_SERVICE)  # the node registers it after every other service
            return True
        except rosgraph.MasterError:  # not registered yet
            return False

    def _set_params(self, robot: RobotSpec, seed: int) -> None:
        master = self._master()
        sim_params = yaml.safe_load(robot.sim_config_path.read_text())
        master.setParam("/use_sim_time", True)
        master.setParam("/robot_description", robot.urdf_path.read_text())
        master.setParam("/pybullet_sim", {**sim_params, "paused": True, "seed": int(seed), "gui": False})

    def close(self) -> None:
        """End the sim node, then the master (bounded); idempotent."""
        for process in reversed(self.processes):
            stop_process(process)
        self.processes = []
        for log in self._logs:
            log.close()
        self._logs = []
