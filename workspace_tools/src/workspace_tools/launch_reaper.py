"""Ends every process of a launch once its launcher has ended, however the launcher ended (kill -9 too).

roslaunch starts its nodes in sessions of their own, so a launcher killed with SIGKILL leaves the master,
rosout and the nodes running forever, reparented to PID 1. `watch_launch()` marks the launcher's
environment with a value every process it starts inherits, and starts this module as a watcher in a
session of its own (untouched by the terminal's Ctrl-C and hang-up) that holds the read end of a pipe
only the launcher can write: when the launcher ends, the pipe closes, and the watcher ends every
process still carrying the mark (SIGTERM, then SIGKILL), then itself.

  python -m workspace_tools.launch_reaper MARK     (stdin: the pipe; started by watch_launch)
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

MARK_VARIABLE = "ROBOT_RL_LAUNCH"
GRACE_S = 5.0     # between SIGTERM and SIGKILL
SWEEPS = 5        # a process may start another while the first are ending: look again


def processes_with(variable: str, value: str) -> list[int]:
    """Pids of the processes (other than this one) whose environment sets `variable` to `value`."""
    wanted = f"{variable}={value}".encode()
    pids = []
    for entry in os.scandir("/proc"):
        if entry.name.isdigit() and int(entry.name) != os.getpid():
            try:
                environ = Path(entry.path, "environ").read_bytes().split(b"\0")
            except OSError:  # gone, a zombie, or a kernel thread
                continue
            if wanted in environ:
                pids.append(int(entry.name))
    return pids


def descendants(pid: int) -> list[int]:
    """Pids of every live process below `pid` (from /proc's parent links)."""
    children: dict[int, list[int]] = {}
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                parent = int(Path(entry.path, "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):  # gone
                continue
            children.setdefault(parent, []).append(int(entry.name))
    found, todo = [], [pid]
    while todo:
        below = children.get(todo.pop(), [])
        found.extend(below)
        todo.extend(below)
    return found


def _signal_all(pids: list[int], signum: int) -> None:
    for pid in pids:
        try:
            os.kill(pid, signum)
        except ProcessLookupError:
            pass


def end_marked_processes(mark: str) -> None:
    """SIGTERM every process carrying `mark`, SIGKILL what is left after GRACE_S; bounded."""
    for _ in range(SWEEPS):
        pids = processes_with(MARK_VARIABLE, mark)
        if not pids:
            return
        _signal_all(pids, signal.SIGTERM)
        deadline = time.monotonic() + GRACE_S
        while (pids := processes_with(MARK_VARIABLE, mark)) and time.monotonic() < deadline:
            time.sleep(0.1)  # processes we did not start: no notification of their end exists
        _signal_all(pids, signal.SIGKILL)


def watch_launch() -> None:
    """Mark this process's environment (inherited by everything it starts from now on) and start the
    watcher that ends every marked process once this process has ended."""
    mark = f"{os.getpid()}-{uuid.uuid4().hex[:12]}"
    read, write = os.pipe()  # both non-inheritable: only the watcher gets the read end, as its stdin
    environment = {key: value for key, value in os.environ.items() if not key.startswith("ROS_")}  # not a ROS process
    subprocess.Popen([sys.executable, "-m", __name__, mark], stdin=read, start_new_session=True, env=environment,
                     stdout=subprocess.DEVNULL)
    os.close(read)
    os.environ[MARK_VARIABLE] = mark
    # `write` stays open, unused, until this process ends: its closing is the watcher's signal.


def main(argv: list[str]) -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    while sys.stdin.buffer.read(4096):  # EOF once the launcher, the pipe's only writer, has ended
        pass
    end_marked_processes(argv[0])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
