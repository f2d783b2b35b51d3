"""evaluate.py --push over ROS (the sim node's /gazebo/get_model_state and set_model_state) kicks the base as the
direct backend does: the same seeded episodes, the same figures."""
import json

from workspace_tools.processes import launch_args

EVALUATE = ["rosrun", "hopper_training", "evaluate.py", "--policy", "controller", "--task", "end_to_end",
            "--episodes", "1", "--horizon-s", "3", "--seed", "1000", "--push", "0.3"]


def test_pushes_over_ros_are_the_direct_backends(ros_master):
    direct = ros_master.run(EVALUATE, timeout=120)
    assert direct.returncode == 0, direct.stderr[-3000:]
    ros_master.start(["roslaunch", "pybullet_sim", "hopper_sim.launch", *launch_args(paused="true", seed=1000)])
    over_ros = ros_master.run([*EVALUATE, "--backend", "ros"], timeout=300)
    assert over_ros.returncode == 0, over_ros.stderr[-3000:]
    reports = [json.loads(run.stdout.strip().splitlines()[-1]) for run in (direct, over_ros)]
    assert reports[0]["push"] == reports[1]["push"] == 0.3
    assert reports[1]["controller"] == reports[0]["controller"]
