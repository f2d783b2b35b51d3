"""The training runs `./ws run` has going on this machine, so that `./ws plot`, `./ws rviz` and `./ws exec` in
another terminal reach the run's ROS master without anyone exporting ROS_MASTER_URI.

`./ws run` takes ROS's default master port (11311) when it is free, a free port only when it is taken
(`run_master_uri`). A run that takes 11311 claims it in the runs folder (`port-11311.claim`, its pid: ./ws execs
into the launcher) before its master is up, so that a second `./ws run` started in the same second takes another
port instead of the same one; the launcher removes the claim when it ends, and a claim whose process is gone
counts for nothing. roslaunch_checked.py, once the master is up, writes one JSON file per run into the runs folder
(`.ws/runs/`, or $WS_RUNS_DIR): the launcher's pid, the master's URI, roslaunch's /run_id, the command and when it
started; it removes the file when it ends. A file outlives its run only if the launcher is killed with SIGKILL:
`live_runs()` then finds its pid gone and removes it, and skips any run whose master does not answer with the
/run_id recorded (a later master on the same port is another run's).
"""
from __future__ import annotations

import fcntl
import json
import os
import socket
import time
import xmlrpc.client
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from workspace_tools.paths import REPO

DEFAULT_PORT = 11311               # ROS's default master port
RECORD_VARIABLE = "WS_RUN_RECORD"  # set by ./ws run: the folder roslaunch_checked.py records the run in
ANSWER_TIMEOUT_S = 2.0             # a master that does not answer within this is not joined


def runs_folder() -> Path:
    """Where ./ws run records its runs: $WS_RUNS_DIR, else the checkout's .ws/runs/."""
    return Path(os.environ.get("WS_RUNS_DIR") or REPO / ".ws" / "runs")


def port_is_free(port: int, host: str = "127.0.0.1") -> bool:
    """Whether a server could listen on host:port now (as rosmaster does: SO_REUSEADDR, so a closed master's
    connections in TIME_WAIT do not count)."""
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError:
            return False
    return True


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextmanager
def _default_port_claim(folder: Path) -> Iterator[tuple[Path, int]]:
    """Under the runs folder's lock: (the claim file of DEFAULT_PORT, the pid it names; 0 if none or unreadable)."""
    folder.mkdir(parents=True, exist_ok=True)
    claim = folder / f"port-{DEFAULT_PORT}.claim"
    with open(folder / "ports.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            holder = int(claim.read_text())
        except (OSError, ValueError):
            holder = 0
        yield claim, holder


def claim_default_port(folder: Path) -> bool:
    """Whether this process takes DEFAULT_PORT: free, and claimed by no other live process (a run whose master is
    not up yet). If so, the claim is this process's (written under a lock, so two callers never both take it)."""
    with _default_port_claim(folder) as (claim, holder):
        if holder > 0 and holder != os.getpid() and _alive(holder) or not port_is_free(DEFAULT_PORT):
            return False
        claim.write_text(f"{os.getpid()}\n")
    return True


def release_default_port(folder: Path) -> None:
    """Remove this process's claim on DEFAULT_PORT (its run ends), if it holds one."""
    if not (folder / f"port-{DEFAULT_PORT}.claim").is_file():
        return
    with _default_port_claim(folder) as (claim, holder):
        if holder == os.getpid():
            claim.unlink(missing_ok=True)


def run_master_uri() -> tuple[str, str]:
    """(ROS_MASTER_URI for a new run, the one line that says which): 11311 if free and unclaimed (claimed for this
    process then), else a free port."""
    if claim_default_port(runs_folder()):
        return f"http://127.0.0.1:{DEFAULT_PORT}", f"this run's ROS master: http://127.0.0.1:{DEFAULT_PORT} (./ws " \
                                                   f"plot, rviz and exec in another terminal join it)"
    uri = f"http://127.0.0.1:{free_port()}"
    return uri, f"port {DEFAULT_PORT} is taken (another ROS master, or a run starting?): this run's ROS master is " \
                f"{uri} (./ws plot, rviz and exec in another terminal join it)"


@dataclass(frozen=True)
class LiveRun:
    """A run recorded by roslaunch_checked.py."""

    path: Path
    pid: int
    master_uri: str
    run_id: str
    command: str
    started: float   # time.time()
    robot: str = ""  # as ./ws names it (workspace_tools.robots)

    def describe(self) -> str:
        """One line: which run this is."""
        when = time.strftime("%H:%M:%S", time.localtime(self.started))
        return f"`{self.command}` (pid {self.pid}, started {when}), its master {self.master_uri}"


def record(folder: Path, master_uri: str, run_id: str, command: str, robot: str = "") -> Path:
    """Write this process's run file (whole: written aside, then renamed); returns its path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{os.getpid()}.json"
    partial = folder / f".{os.getpid()}.partial"
    partial.write_text(json.dumps({"pid": os.getpid(), "master_uri": master_uri, "run_id": run_id,
                                   "command": command, "robot": robot, "started": time.time()}) + "\n")
    os.replace(partial, path)
    return path


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def _answers(master_uri: str, run_id: str) -> bool:
    """Whether the master at master_uri answers, within ANSWER_TIMEOUT_S, with this /run_id."""
    class Transport(xmlrpc.client.Transport):
        def make_connection(self, host):
            connection = super().make_connection(host)
            connection.timeout = ANSWER_TIMEOUT_S
            return connection
    try:
        answer: Any = xmlrpc.client.ServerProxy(master_uri, transport=Transport()).getParam("/ws", "/run_id")
        code, _, value = answer
    except (OSError, xmlrpc.client.Error, ValueError, TypeError):
        return False
    return bool(code == 1 and value == run_id)


def _read(path: Path) -> LiveRun | None:
    try:
        data = json.loads(path.read_text())
        return LiveRun(path, int(data["pid"]), str(data["master_uri"]), str(data["run_id"]), str(data["command"]),
                       float(data["started"]), str(data.get("robot", "")))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def live_runs(folder: Path | None = None) -> list[LiveRun]:
    """The recorded runs whose master answers, newest first; the files of runs whose launcher is gone (or that
    cannot be read) are removed."""
    folder = folder or runs_folder()
    found = []
    for path in sorted(folder.glob("*.json")) if folder.is_dir() else []:
        run = _read(path)
        if run is None or not _alive(run.pid):
            path.unlink(missing_ok=True)
            continue
        if _answers(run.master_uri, run.run_id):
            found.append(run)
    return sorted(found, key=lambda run: run.started, reverse=True)


def join_line(runs: list[LiveRun]) -> str:
    """The one line a command that joins runs[0] prints."""
    others = f" (the newest of {len(runs)} runs; set ROS_MASTER_URI to join another)" if len(runs) > 1 else ""
    return f"joining the run of {runs[0].describe()}{others}"
