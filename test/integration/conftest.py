"""Fixtures for integration tests that need a real ROS master: each gets its own on a free port,
and every process a test starts is ended by its PID (process group) when the test ends."""
from __future__ import annotations

from pathlib import Path

import pytest

from workspace_tools.processes import Processes, RosMaster, launch_args, stop  # noqa: F401 (used by the tests)

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def ros_master(tmp_path):
    master = RosMaster(tmp_path, cwd=REPO)
    try:
        yield master
    finally:
        master.close()
