"""The monoped's crouched, tilted start over ROS (Gazebo's set_model_configuration and set_model_state on the
sim node) gives the same episode as on the direct backend."""
import json

from workspace_tools.paths import PROGRAMS
from workspace_tools.processes import launch_args


def test_the_tilted_crouch_over_ros_is_the_direct_backends(ros_master):
    ros_master.start(["roslaunch", "pybullet_sim", "hopper_sim.launch", *launch_args(paused="true", seed=5)])
    result = ros_master.run(["python", str(PROGRAMS / "monoped_start_both_backends.py")], timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert len(report["ros"]) == 26
    assert report["ros"] == report["direct"]
    first = report["ros"][0]
    assert 0.015 < max(abs(first[1]), abs(first[2])) < 0.055  # leaning: roll and pitch from the IMU
    assert abs(first[6] - 0.476) < 1e-3 and abs(first[7] + 0.9) < 1e-3  # hfe, kfe: the crouch
