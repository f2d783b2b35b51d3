"""The catkin route, as a ROS user takes it: the repository as the `src` of a throwaway catkin workspace,
`catkin_make install`, then a sim launched by package name from the install space alone, and one
rostest run through the `run_tests` target that add_rostest makes."""
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from workspace_tools.paths import REPO
from workspace_tools.processes import Processes, RosMaster

# Variables the workspace's own devel space sets; the install space must work without them.
WORKSPACE_VARIABLES = ("ROS_PACKAGE_PATH", "PYTHONPATH", "CMAKE_PREFIX_PATH", "LD_LIBRARY_PATH", "PKG_CONFIG_PATH",
                       "ROSLISP_PACKAGE_DIRECTORIES")


def in_workspace(workspace: Path, setup: str, command: str) -> list:
    """bash -c that sources `setup` (devel or install space) of `workspace` first, then runs `command`."""
    return ["bash", "-c", f"source {workspace / setup / 'setup.bash'} && {command}"]


@pytest.fixture(scope="module")
def catkin_workspace(tmp_path_factory):
    workspace = tmp_path_factory.mktemp("catkin_ws")
    (workspace / "src").symlink_to(REPO)
    env = {k: v for k, v in os.environ.items() if k not in WORKSPACE_VARIABLES}
    build = subprocess.run(["catkin_make", "-C", str(workspace), "install", f"-DPYTHON_EXECUTABLE={sys.executable}",
                            "-DCATKIN_ENABLE_TESTING=ON"], cwd=workspace, env=env, capture_output=True, text=True,
                           timeout=900)
    assert build.returncode == 0, build.stdout[-4000:] + build.stderr[-4000:]
    return workspace, env


def test_catkin_make_install_gives_a_working_install_space(catkin_workspace, tmp_path):
    workspace, env = catkin_workspace
    install = workspace / "install"
    for installed in ("lib/pybullet_sim/sim_node.py", "lib/moving_cube_training/start_training.py",
                      "lib/hopper_training/evaluate.py", "share/pybullet_sim/launch/cube_sim.launch",
                      "share/moving_cube_training/launch/main.launch", "share/hopper_training/config/stay_up.yaml",
                      "share/moving_cube_description/urdf/moving_cube.urdf",
                      "share/hopper_description/config/hopper_sim.yaml", "share/robot_rl/launch/train.launch"):
        assert (install / installed).exists(), f"catkin_make install did not install {installed}"

    master = RosMaster(tmp_path)
    master.env = {k: v for k, v in master.env.items() if k not in WORKSPACE_VARIABLES}
    try:
        find = master.run(in_workspace(workspace, "install", "rospack find pybullet_sim"), timeout=60)
        assert find.stdout.strip() == str(install / "share" / "pybullet_sim"), find.stdout + find.stderr
        with open(tmp_path / "sim.log", "w") as log:
            master.start(in_workspace(workspace, "install", "exec roslaunch pybullet_sim cube_sim.launch "
                                      "paused:=false robot_state_publisher:=false"), stdout=log, stderr=log)
        echo = master.run(in_workspace(workspace, "install", "rostopic echo -n 1 /moving_cube/odom/child_frame_id"),
                          timeout=60)
        assert echo.returncode == 0 and "cube_body" in echo.stdout, \
            echo.stdout + echo.stderr + (tmp_path / "sim.log").read_text()[-3000:]
        node = master.run(in_workspace(workspace, "install", "rosnode info /pybullet_sim"), timeout=60)
        assert str(install / "lib" / "pybullet_sim" / "sim_node.py") in _command_line(node.stdout), node.stdout
    finally:
        master.close()


def _command_line(rosnode_info: str) -> str:
    """The sim node's command line, from its pid as `rosnode info` gives it."""
    pid = next(line.split()[-1] for line in rosnode_info.splitlines() if line.startswith("Pid:"))
    return Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")


def test_run_tests_target_runs_a_rostest(catkin_workspace, tmp_path):
    workspace, env = catkin_workspace
    runner = Processes(tmp_path, cwd=workspace)
    runner.env = {**{k: v for k, v in runner.env.items() if k not in WORKSPACE_VARIABLES},
                  "ROS_MASTER_URI": "http://127.0.0.1:1"}  # rostest starts its own master on a free port
    started = time.monotonic()
    try:
        result = runner.run(in_workspace(workspace, "devel", f"catkin_make -C {workspace} "
                                         "run_tests_workspace_tests_rostest_rostest_cube_lockstep.test"),
                            timeout=600)
    finally:
        runner.close()
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-4000:]
    assert "SUMMARY" in output and "* RESULT: SUCCESS" in output, output[-4000:]
    assert time.monotonic() - started < 600
