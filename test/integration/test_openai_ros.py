"""openai_ros's own task envs (MovingCubeOneDiskWalk-v0, HopperStayUp-v0) on the sims, as docs/guide/tutorials.md
runs them: run_openai_ros_envs.py with their era's gym, against a private master; openai_ros launches the
sim from this workspace's start_world.launch files and clones nothing.

openai_ros is on neither PyPI nor Debian: the tests run only when OPENAI_ROS_WS names a catkin workspace in
which it is built. OPENAI_ROS_PYTHON names a python with gym 0.10.5 and GitPython; without it, one is made
as docs/guide/tutorials.md makes it (from PyPI)."""
from __future__ import annotations

import json
import math
import os
import subprocess

import pytest

from workspace_tools.paths import REPO

OPENAI_ROS_WS = os.environ.get("OPENAI_ROS_WS", "")
RUNNER = REPO / "workspace_tools" / "scripts" / "run_openai_ros_envs.py"
EPISODES, STEPS = 2, 15
# robot: (env id, its world package, observation length, index and start value of a coordinate reset restores)
ENVS = {"cube": ("MovingCubeOneDiskWalk-v0", "moving_cube_description", 6, 1, 0.0),   # y distance from start
        "hopper": ("HopperStayUp-v0", "legged_robots_sims", 11, 10, 1.0)}             # base height

pytestmark = pytest.mark.skipif(
    not OPENAI_ROS_WS,
    reason="set OPENAI_ROS_WS to a catkin workspace with The Construct's openai_ros built in it "
           "(docs/guide/tutorials.md): openai_ros is on neither PyPI nor Debian, and CI reaches only PyPI, Debian and "
           "npm")


@pytest.fixture(scope="module")
def gym_era_python(tmp_path_factory) -> str:
    """A python with openai_ros's era of gym and GitPython: OPENAI_ROS_PYTHON, or a venv made as the docs make it."""
    if os.environ.get("OPENAI_ROS_PYTHON"):
        return os.environ["OPENAI_ROS_PYTHON"]
    venv = tmp_path_factory.mktemp("gym-era")
    subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", str(venv)], check=True, timeout=120)
    subprocess.run([str(venv / "bin" / "pip"), "install", "-q", "gym==0.10.5", "GitPython"], check=True, timeout=600)
    return str(venv / "bin" / "python")


@pytest.mark.parametrize("robot", sorted(ENVS))
def test_openai_ros_task_env_resets_and_steps_on_the_sim(robot, ros_master, gym_era_python):
    env_id, world_package, observation_size, reset_index, reset_value = ENVS[robot]
    result = ros_master.run([gym_era_python, str(RUNNER), robot, OPENAI_ROS_WS, "--episodes", str(EPISODES),
                             "--steps", str(STEPS), "--timeout", "120"], timeout=600)
    output, log = result.stdout + result.stderr, result.stdout[-3000:] + result.stderr[-6000:]
    assert result.returncode == 0, log
    # openai_ros found its launch files in this workspace, so it cloned nothing
    assert f"Package found in workspace-->{REPO / world_package}" in output, log
    assert "lets Download it" not in output, log
    episodes = [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
    assert [episode["episode"] for episode in episodes] == list(range(EPISODES)), log
    for episode in episodes:
        assert episode["env"] == env_id and 1 <= episode["steps"] <= STEPS, episode
        assert episode["done"] or episode["steps"] == STEPS, episode
        assert math.isfinite(episode["return"]), episode
        for observation in (episode["first_observation"], episode["last_observation"]):
            assert len(observation) == observation_size and all(map(math.isfinite, observation)), episode
        # every reset (the env's Gazebo reset service) put the robot back where it starts
        assert episode["first_observation"][reset_index] == pytest.approx(reset_value, abs=0.1), episode
    assert any(episode["first_observation"] != episode["last_observation"] for episode in episodes), \
        f"the robot never moved: {episodes}"
    # what the env launched (the sim, robot_state_publisher, two roslaunch) ended with the runner
    assert ros_master.leftovers() == [], "processes the env launched outlived the runner"
