"""A sim launch says nothing it does not explain: robot_state_publisher's kdl_parser warning about the root
link's inertia is not shown (pybullet_sim/config/robot_state_publisher.rosconsole says why; rviz's
`media_export` error is test_display.py's)."""
import subprocess
import time

import pytest

from workspace_tools.processes import launch_args, stop

KDL_WARNING = "KDL does not support a root link with an inertia"
START_TIMEOUT = 60.0  # wall s for robot_state_publisher to advertise /tf on a busy 2-core machine


def publishes(master, node: str, topic: str) -> bool:
    publishers, _, _ = master.params.getSystemState()
    return node in dict(publishers).get(topic, [])


@pytest.mark.parametrize("robot", ["cube", "hopper"])
def test_a_sim_launch_logs_no_kdl_root_inertia_warning(ros_master, tmp_path, robot):
    log = tmp_path / "roslaunch.log"
    with open(log, "w") as out:
        launch = ros_master.start(["roslaunch", "pybullet_sim", f"{robot}_sim.launch", *launch_args(paused="false")],
                                  stdout=out, stderr=subprocess.STDOUT)
    # kdl_parser warns while robot_state_publisher reads the URDF, before it advertises /tf.
    deadline = time.monotonic() + START_TIMEOUT
    while not publishes(ros_master, "/robot_state_publisher", "/tf"):
        assert launch.poll() is None and time.monotonic() < deadline, \
            f"robot_state_publisher did not advertise /tf within {START_TIMEOUT} s:\n{log.read_text()[-3000:]}"
        time.sleep(0.1)
    stop(launch)
    output = log.read_text() + "".join(path.read_text(errors="replace") for path in tmp_path.rglob("*.log"))
    assert "process[robot_state_publisher-" in output, output[-3000:]
    assert KDL_WARNING not in output, output[-3000:]
