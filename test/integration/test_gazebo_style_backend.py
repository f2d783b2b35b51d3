"""robot_rl.backends.GazeboStyleBackend against a real sim node: a normal env stepped as the tutorials step
Gazebo (unpause, publish, wait on /clock, pause, read the latest messages), as ./ws bench measures it."""
import json
import sys
from pathlib import Path

from workspace_tools.processes import RosMaster, launch_args

REPO = Path(__file__).resolve().parents[2]
# One client process (a process is one ROS node): 10 steps of action 0 (haa target + increment) on the monoped.
CLIENT = """
import json
import rospy
from hopper_training.envs.stay_up import STAY_UP
from robot_rl import GazeboStyleBackend
from robot_rl import make_env

rospy.wait_for_service("/pybullet_sim/step", 60)  # the launch has set /use_sim_time by then
rospy.init_node("gazebo_style_client")
backend = GazeboStyleBackend(STAY_UP.robot)
env = make_env(STAY_UP, backend=backend)
observation, _ = env.reset(seed=0)
report = {"haa": [float(observation[5])], "clock": [], "sim_time": [], "paused": []}
for _ in range(10):
    before = rospy.get_rostime().to_sec()
    observation, _, _, _, info = env.step(0)
    report["clock"].append((before, rospy.get_rostime().to_sec()))
    report["sim_time"].append(info["sim_time"])
    report["haa"].append(float(observation[5]))
    report["paused"].append(backend.sim.is_paused())
report["running_step"] = env.unwrapped.running_step
env.close()
print(json.dumps(report))
"""


def test_a_gazebo_style_step_advances_running_step_and_leaves_the_sim_paused(tmp_path):
    master = RosMaster(tmp_path, cwd=REPO)
    try:
        master.start(["roslaunch", "pybullet_sim", "hopper_sim.launch", *launch_args(paused="true")])
        result = master.run([sys.executable, "-c", CLIENT], timeout=120)
    finally:
        master.close()
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert all(report["paused"]), "each step pauses the sim again"
    for before, after in report["clock"]:
        assert after >= before + report["running_step"] - 1e-9, "a step lasts at least running_step of sim time"
    assert report["sim_time"] == sorted(report["sim_time"]) and report["sim_time"][-1] > report["sim_time"][0]
    # The commands went out on the command topics: haa followed its target up (0.05 rad an action).
    assert report["haa"][-1] > report["haa"][0] + 0.1
