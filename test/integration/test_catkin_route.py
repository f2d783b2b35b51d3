"""The catkin route, as a ROS user takes it (docs/guide/tutorials.md): the repository as the `src` of a throwaway
catkin workspace, `catkin_make install` with the venv's python, then, in a shell where that venv is not
active and the first python3 on PATH is not it, from the install space alone: the sim and a short
training launched by package name, the systems test through roslaunch_checked.py (its exit code, PASS
and FAIL) and a rostest by package name; and every rostest through `catkin_make run_tests` and
`catkin_test_results`."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from workspace_tools.paths import REPO, ROSTESTS
from workspace_tools.processes import Processes, RosMaster

# Variables the workspace's own devel space and venv set; a user's shell has none of them.
WORKSPACE_VARIABLES = ("ROS_PACKAGE_PATH", "PYTHONPATH", "CMAKE_PREFIX_PATH", "LD_LIBRARY_PATH", "PKG_CONFIG_PATH",
                       "ROSLISP_PACKAGE_DIRECTORIES", "VIRTUAL_ENV")
VENV_PYTHON = sys.executable  # the interpreter catkin is given, as the recipe's -DPYTHON_EXECUTABLE
BANNER = "REQUIRED process"


def user_shell(env: dict) -> dict:
    """`env` as a user's shell has it before `source .../setup.bash`: no workspace variables, no venv on PATH."""
    venv_bin = str(Path(VENV_PYTHON).parent)
    path = ":".join(entry for entry in env["PATH"].split(":") if entry != venv_bin)
    return {**{k: v for k, v in env.items() if k not in WORKSPACE_VARIABLES}, "PATH": path}


def in_workspace(workspace: Path, setup: str, command: str) -> list:
    """bash -c that sources `setup` (devel or install space) of `workspace` first, then runs `command`."""
    return ["bash", "-c", f"source {workspace / setup / 'setup.bash'} && {command}"]


@pytest.fixture(scope="module")
def catkin_workspace(tmp_path_factory):
    workspace = tmp_path_factory.mktemp("catkin_ws")
    (workspace / "src").symlink_to(REPO)
    build = subprocess.run(["catkin_make", "-C", str(workspace), "install", f"-DPYTHON_EXECUTABLE={VENV_PYTHON}",
                            "-DCATKIN_ENABLE_TESTING=ON"], cwd=workspace, env=user_shell(dict(os.environ)),
                           capture_output=True, text=True, timeout=900)
    assert build.returncode == 0, build.stdout[-4000:] + build.stderr[-4000:]
    return workspace


@pytest.fixture
def install_space_master(tmp_path):
    """A private master; the processes started through it run in a user's shell."""
    master = RosMaster(tmp_path, cwd=tmp_path)
    master.env = user_shell(master.env)
    try:
        yield master
    finally:
        master.close()


def test_the_first_python3_on_path_is_not_the_venv():
    """What makes this test a user's: without the shebangs of the install space, nodes would run with it."""
    first = subprocess.run(["bash", "-c", "command -v python3"], env=user_shell(dict(os.environ)),
                           capture_output=True, text=True, timeout=30).stdout.strip()
    assert first and Path(first).parent != Path(VENV_PYTHON).parent, first


def test_catkin_make_install_gives_a_working_install_space(catkin_workspace, install_space_master, tmp_path):
    install, master = catkin_workspace / "install", install_space_master
    for installed in ("lib/pybullet_sim/sim_node.py", "lib/moving_cube_training/start_training.py",
                      "lib/hopper_training/evaluate.py", "share/pybullet_sim/launch/cube_sim.launch",
                      "share/moving_cube_training/launch/main.launch", "share/hopper_training/config/stay_up.yaml",
                      "share/moving_cube_description/urdf/moving_cube.urdf",
                      "share/hopper_description/config/hopper_sim.yaml", "share/robot_rl/launch/train.launch",
                      "share/workspace_tests/rostest/cube_lockstep.test", "lib/workspace_tests/cube_lockstep_node.py",
                      "lib/workspace_tests/hopper_check_env.py"):
        assert (install / installed).exists(), f"catkin_make install did not install {installed}"
    for script in install.glob("lib/*/*.py"):
        if os.access(script, os.X_OK):
            first_line = script.read_text().splitlines()[0]
            assert first_line == f"#!{VENV_PYTHON}", f"{script} starts with {first_line}, not the catkin's python"

    find = master.run(in_workspace(catkin_workspace, "install", "rospack find pybullet_sim"), timeout=60)
    assert find.stdout.strip() == str(install / "share" / "pybullet_sim"), find.stdout + find.stderr
    with open(tmp_path / "sim.log", "w") as log:
        master.start(in_workspace(catkin_workspace, "install", "exec roslaunch pybullet_sim cube_sim.launch "
                                  "paused:=false robot_state_publisher:=false"), stdout=log, stderr=log)
    echo = master.run(in_workspace(catkin_workspace, "install", "rostopic echo -n 1 /moving_cube/odom/child_frame_id"),
                      timeout=60)
    assert echo.returncode == 0 and "cube_body" in echo.stdout, \
        echo.stdout + echo.stderr + (tmp_path / "sim.log").read_text()[-3000:]
    node = master.run(in_workspace(catkin_workspace, "install", "rosnode info /pybullet_sim"), timeout=60)
    assert str(install / "lib" / "pybullet_sim" / "sim_node.py") in _command_line(node.stdout), node.stdout


def _command_line(rosnode_info: str) -> str:
    """The sim node's command line, from its pid as `rosnode info` gives it."""
    pid = next(line.split()[-1] for line in rosnode_info.splitlines() if line.startswith("Pid:"))
    return Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")


@pytest.mark.parametrize("launcher", ["roslaunch", "rosrun workspace_tools roslaunch_checked.py"])
def test_a_training_runs_from_the_install_space(catkin_workspace, install_space_master, tmp_path, launcher):
    """The recipe's `roslaunch moving_cube_training main.launch nepisodes:=... results_dir:=...`, 3 episodes;
    through roslaunch_checked.py, without roslaunch's banner."""
    results = tmp_path / "training_results"
    launch = install_space_master.run(in_workspace(
        catkin_workspace, "install", f"{launcher} moving_cube_training main.launch nepisodes:=3 video:=false "
                                     f"results_dir:={results}"), timeout=300)
    output = launch.stdout + launch.stderr
    summaries = [path for path in results.glob("moving_cube/*/summary.json") if not path.parent.is_symlink()]
    assert launch.returncode == 0 and len(summaries) == 1, output[-4000:]
    summary = json.loads(summaries[0].read_text())
    assert summary["completed"] is True, summary
    assert len((summaries[0].parent / "episodes.csv").read_text().splitlines()) == 1 + 3, output[-4000:]
    if launcher != "roslaunch":
        assert BANNER not in output, output[-4000:]


def systems_test(workspace: Path, master: RosMaster, launch: str) -> subprocess.CompletedProcess:
    """The documented command: the systems test launch through roslaunch_checked.py, from the install space."""
    return master.run(in_workspace(workspace, "install", f"rosrun workspace_tools roslaunch_checked.py {launch}"),
                      timeout=180)


def test_the_systems_test_exits_0_on_pass_without_the_banner(catkin_workspace, install_space_master):
    result = systems_test(catkin_workspace, install_space_master, "moving_cube_training systems_test.launch")
    output = result.stdout + result.stderr
    assert result.returncode == 0 and "PASS: the wheel reached" in output, output[-4000:]
    assert BANNER not in output, output[-4000:]


def test_the_systems_test_exits_1_on_fail(catkin_workspace, install_space_master, tmp_path):
    """A sim whose wheel controller is too weak to reach 80 rad/s in 2 s: FAIL, exit code 1."""
    weak = tmp_path / "weak_wheel.launch"
    weak.write_text('<launch>\n  <include file="$(find moving_cube_training)/launch/systems_test.launch"/>\n'
                    '  <param name="/pybullet_sim/controllers/inertia_wheel_roll_joint_velocity_controller/pid/p" '
                    'value="0.0001"/>\n</launch>\n')
    result = systems_test(catkin_workspace, install_space_master, str(weak))
    output = result.stdout + result.stderr
    assert result.returncode == 1 and "FAIL: the wheel did not reach 80 rad/s" in output, output[-4000:]
    assert BANNER not in output, output[-4000:]


def test_a_rostest_runs_by_package_name_from_the_install_space(catkin_workspace, install_space_master):
    result = install_space_master.run(in_workspace(catkin_workspace, "install",
                                                   "rostest workspace_tests cube_lockstep.test"), timeout=600)
    output = result.stdout + result.stderr
    assert result.returncode == 0 and "* RESULT: SUCCESS" in output, output[-4000:]


def test_run_tests_runs_every_rostest_and_catkin_test_results_passes(catkin_workspace, tmp_path):
    runner = Processes(tmp_path, cwd=catkin_workspace)
    runner.env = {**user_shell(runner.env), "ROS_MASTER_URI": "http://127.0.0.1:1"}  # rostest starts its own masters
    try:
        run_tests = runner.run(in_workspace(catkin_workspace, "devel", f"catkin_make -C {catkin_workspace} run_tests"),
                               timeout=1800)
        results = runner.run(in_workspace(catkin_workspace, "devel", "catkin_test_results build/test_results"),
                             timeout=60)
    finally:
        runner.close()
    assert run_tests.returncode == 0, (run_tests.stdout + run_tests.stderr)[-4000:]
    result_files = sorted(catkin_workspace.glob("build/test_results/workspace_tests/rostest-*.xml"))
    assert len(result_files) == len(list(ROSTESTS.glob("*.test"))), result_files
    # catkin_make run_tests exits 0 whatever the tests did: catkin_test_results' exit code is the verdict.
    assert results.returncode == 0 and " 0 errors, 0 failures" in results.stdout, \
        results.stdout[-4000:] + run_tests.stdout[-4000:]
