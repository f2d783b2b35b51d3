"""Fixtures for integration tests that need a real ROS master: each gets its own on a free port,
and every process a test starts is ended by its PID (process group) when the test ends."""
from __future__ import annotations

import os
import select
import subprocess
from pathlib import Path

import pytest

from workspace_tools.paths import REPO
from workspace_tools.processes import Processes, RosMaster


@pytest.fixture
def ros_master(tmp_path):
    master = RosMaster(tmp_path, cwd=REPO)
    try:
        yield master
    finally:
        master.close()


@pytest.fixture
def master(tmp_path):
    """A private master; at the end, nothing may be left running against it (the leftovers are named)."""
    ros = RosMaster(tmp_path / "ros", cwd=REPO)
    try:
        yield ros
        assert ros.leftovers() == [], "processes left running: " + ", ".join(
            Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")[:120] for pid in ros.leftovers())
    finally:
        ros.close()


@pytest.fixture
def xvfb(tmp_path):
    """A virtual X display (Debian's Xvfb, which ./ws test installs) on a free display number: yields
    its DISPLAY (":N"); Xvfb is ended by its PID."""
    processes, log = Processes(tmp_path), tmp_path / "xvfb.log"
    read, write = os.pipe()
    try:
        with open(log, "w") as out:
            # -noreset: by default the X server resets when its last client leaves, and a screenshot taken
            # then fails to connect ("X connection failed: error 1", 5 of 71 runs of the plot window test)
            xvfb = processes.start(["Xvfb", "-displayfd", str(write), "-screen", "0", "1024x768x24", "-noreset",
                                    "-nolisten", "tcp"], pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=out)
        os.close(write)
        write = -1
        ready, _, _ = select.select([read], [], [], 20.0)  # Xvfb writes its display number once it accepts clients
        number = os.read(read, 32).decode().strip() if ready else ""
        if not number.isdigit():
            raise RuntimeError(f"Xvfb reported no display within 20 s (exit code {xvfb.poll()}, log {log}); "
                               f"./ws test installs Debian's xvfb")
        yield f":{number}"
    finally:
        for fd in (read, write):
            if fd >= 0:
                os.close(fd)
        processes.close()
