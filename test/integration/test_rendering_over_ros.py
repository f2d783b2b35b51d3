"""Frames over ROS: the env's rgb_array frames come from the sim node's ~render service and equal the
direct backend's, before and after the robot moves; the contact_markers node draws the monoped's foot force."""
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from workspace_tools.paths import PROGRAMS
from workspace_tools.processes import launch_args

SCRIPT = PROGRAMS / "render_over_ros.py"


@pytest.mark.parametrize("robot, env_id", [("cube", "MovingCubeOneDiskWalk-v0"), ("hopper", "Monoped-v0")])
def test_frames_over_ros_equal_the_direct_ones_and_change_when_the_robot_moves(ros_master, robot, env_id):
    ros_master.start(["roslaunch", "pybullet_sim", f"{robot}_sim.launch",
                      *launch_args(paused="true", robot_state_publisher="false")])
    markers = robot == "hopper"
    if markers:  # the node reads the robot from the sim's params: start it once roslaunch has set them
        deadline = time.monotonic() + 30.0
        while not ros_master.params.hasParam("/pybullet_sim/robot_namespace"):
            assert time.monotonic() < deadline, "roslaunch did not set /pybullet_sim's params within 30 s"
            time.sleep(0.05)  # bounded poll: the master has no notification for params
        markers_log = ros_master.env["ROS_LOG_DIR"] + "/contact_markers.out"
        with open(markers_log, "w") as out:
            markers_node = ros_master.start(["rosrun", "pybullet_sim", "contact_markers.py"], stdout=out,
                                            stderr=subprocess.STDOUT)
    result = ros_master.run([sys.executable, str(SCRIPT), env_id, *(["--markers"] if markers else [])], timeout=180)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["shape"] == [240, 320, 3] and report["dtype"] == "uint8"
    assert report["std"] > 20.0, "a blank frame"
    assert report["equal_to_direct"] == [True, True], "the sim node renders what the direct backend renders"
    assert report["changed_pixels"] > 0.05, "the frame should change when the robot moves"
    assert "/pybullet_sim/render" in report["bad_size"] and "image size must be whole pixels" in report["bad_size"]
    if markers:
        arrows = [m for m in report["markers"] if m["action"] == 0]  # Marker.ADD
        assert arrows, f"no force arrow while the foot stood on the ground: {report['markers'][:5]}"
        assert all(m["frame"] == "lowerleg_contactsensor_link" and 0.0 < m["length"] <= 1.0 for m in arrows), arrows
        markers_node.send_signal(signal.SIGINT)  # Ctrl-C: rospy shuts down in a thread, spin() ends
        assert markers_node.wait(timeout=10) == 0, Path(markers_log).read_text()[-3000:]
        assert "Traceback" not in Path(markers_log).read_text()
