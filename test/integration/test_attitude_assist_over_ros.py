"""The attitude assist over ROS (the sim node's ~set_attitude_assist): the env's params set it, the episodes are the
direct backend's to the bit, a bad gain is refused with the sim's reason, and the sim gets its own assist back
when the env closes."""
import json
import sys

from workspace_tools.processes import launch_args

SCRIPT = """import json
import numpy as np
import rospy
from hopper_training.envs.end_to_end import END_TO_END
from pybullet_sim.names import ATTITUDE_ASSIST_SERVICE
from pybullet_sim.srv import SetAttitudeAssist
from robot_rl import make_env

params = END_TO_END.default_params().with_changes("test", attitude_assist={"stiffness": 20.0, "damping": 1.0,
                                                                          "scale": 0.5}, nsteps=600)
report = {}
for backend in ("direct", "ros"):
    env = make_env(END_TO_END, params=params, backend=backend, seed=1000)
    observations = []
    env.reset(seed=1000)
    for _ in range(600):  # 3 s of the crouch: it falls in ~1.1 s without the assist
        observation, _, terminated, _, _ = env.step(np.zeros(3, np.float32))
        observations.append(observation.tolist())
        if terminated:
            break
    report[backend] = {"steps": len(observations), "terminated": bool(terminated), "last": observations[-1]}
    if backend == "ros":
        try:
            env.unwrapped.backend.set_attitude_assist(float("nan"), 0.0)
        except ValueError as error:
            report["refused"] = str(error)
    env.close()
answer = rospy.ServiceProxy(ATTITUDE_ASSIST_SERVICE, SetAttitudeAssist)(0.0, 0.0)
report["after_close"] = [answer.previous_stiffness, answer.previous_damping]
print(json.dumps(report))
"""


def test_the_assist_over_ros_is_the_direct_backends_and_the_sim_gets_its_own_back(ros_master, tmp_path):
    ros_master.start(["roslaunch", "pybullet_sim", "hopper_sim.launch", *launch_args(paused="true", seed=1000)])
    script = tmp_path / "assist.py"
    script.write_text(SCRIPT)
    result = ros_master.run([sys.executable, str(script)], timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["direct"] == report["ros"]
    assert report["ros"]["steps"] == 600 and not report["ros"]["terminated"], "half the assist holds the crouch 3 s"
    assert report["refused"].startswith("/pybullet_sim/set_attitude_assist refused: attitude assist stiffness must "
                                        "be a finite number from 0 to 10000, got nan")
    assert report["after_close"] == [0.0, 0.0]
