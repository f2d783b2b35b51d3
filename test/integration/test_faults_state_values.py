"""Absurd but finite values sent to a running sim node over ROS, each robot's sim on its own master: Gazebo's
services refuse a value beyond the sim's bounds (pybullet_sim.validation) with success false naming the field
and the bound, and change nothing; commands beyond a joint's limits are clamped to them, as ros_control does;
the sim keeps answering with finite readings. docs/reference/faults.md lists these cases."""
from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest

PROBE = '''
import json, math, sys
import rospy
from geometry_msgs.msg import Vector3
from gazebo_msgs.msg import ModelState
from gazebo_msgs.srv import GetModelState, GetPhysicsProperties, SetModelState, SetPhysicsProperties
from std_msgs.msg import Float64
from pybullet_sim.ros.client import CommandPublisher, SimConnection

rospy.init_node("absurd_values", anonymous=True)
sim = SimConnection(timeout=30.0)  # waits for the sim's services
model, controllers = sys.argv[1], rospy.get_param("/pybullet_sim/controllers")
namespace = rospy.get_param("/pybullet_sim/robot_namespace")
get_state = rospy.ServiceProxy("/gazebo/get_model_state", GetModelState)
set_state = rospy.ServiceProxy("/gazebo/set_model_state", SetModelState)
get_physics = rospy.ServiceProxy("/gazebo/get_physics_properties", GetPhysicsProperties)
set_physics = rospy.ServiceProxy("/gazebo/set_physics_properties", SetPhysicsProperties)
out = {}

def pose():
    state = get_state(model, "")
    return [state.pose.position.x, state.pose.position.y, state.pose.position.z, state.pose.orientation.x,
            state.pose.orientation.y, state.pose.orientation.z, state.pose.orientation.w, state.twist.linear.x]

def model_state(field, value):
    wanted = ModelState(model_name=model)
    wanted.pose.position.z = 0.5
    wanted.pose.orientation.w = 1.0
    target, attribute = wanted, field.split(".")
    for name in attribute[:-1]:
        target = getattr(target, name)
    setattr(target, attribute[-1], value)
    return wanted

for field, value in (("pose.position.x", 1e30), ("twist.linear.x", 1e30), ("twist.angular.z", -1e30)):
    before = pose()
    answer = set_state(model_state(field, value))
    out[field] = [answer.success, answer.status_message, pose() == before]
huge = model_state("pose.orientation.x", 1e200)
huge.pose.orientation.w = 1e200
answer = set_state(huge)
out["huge_quaternion"] = [answer.success, pose()[3:7]]

physics = get_physics()
for name, time_step, gravity in (("gravity", physics.time_step, Vector3(0.0, 0.0, -1e30)),
                                 ("time_step", 1e30, physics.gravity)):
    answer = set_physics(time_step, physics.max_update_rate, gravity, physics.ode_config)
    now = get_physics()
    out[name] = [answer.success, answer.status_message,
                 (now.time_step, now.gravity.z) == (physics.time_step, physics.gravity.z)]

publishers = [CommandPublisher(f"{namespace}/{name}/command") for name in sorted(controllers)
              if name != "joint_state_controller"]
for publisher in publishers:
    publisher.wait_for_subscriber(30.0)
    publisher.publish(1e30)
sim.reset(restart_time=False)
for publisher in publishers:
    publisher.publish(1e30)
sim.step(500, publishers)
packed = sim.step_packed(1, [], [])
out["readings_finite"] = all(math.isfinite(v) for v in packed.values)
joints = int(packed.values[1])
out["joint_positions"], out["joint_velocities"] = packed.values[2:2 + joints], packed.values[2 + joints:2 + 2 * joints]
sim.close()
print(json.dumps(out))
'''


@pytest.mark.parametrize("launch, model", [("cube_sim.launch", "moving_cube"), ("hopper_sim.launch", "monoped")],
                         ids=["cube", "hopper"])
def test_absurd_but_finite_values_are_refused_or_clamped_and_the_sim_stays_finite(master, tmp_path, launch, model):
    log = tmp_path / "sim.log"
    with open(log, "w") as out:
        sim = master.start(["roslaunch", "pybullet_sim", launch, "robot_state_publisher:=false"], stdout=out,
                           stderr=subprocess.STDOUT)
    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    result = master.run([sys.executable, str(script), model], timeout=120)
    assert result.returncode == 0, result.stderr[-3000:] + log.read_text()[-3000:]
    found = json.loads(result.stdout.strip().splitlines()[-1])

    refused = "SetModelState refused, nothing changed: "
    assert found["pose.position.x"] == [False, refused + "pose.position.x must be a finite number within +-1e+06 m, "
                                        "got 1e+30", True]
    assert found["twist.linear.x"] == [False, refused + "twist.linear.x must be a finite number within +-1000 m/s, "
                                       "got 1e+30", True]
    assert found["twist.angular.z"] == [False, refused + "twist.angular.z must be a finite number within +-1000 "
                                        "rad/s, got -1e+30", True]
    success, orientation = found["huge_quaternion"]
    assert success and orientation == pytest.approx([0.5**0.5, 0.0, 0.0, 0.5**0.5])
    refused = "SetPhysicsProperties refused, nothing changed: "
    assert found["gravity"] == [False, refused + "gravity.z must be a finite number within +-1000 m/s^2, got -1e+30",
                                True]
    assert found["time_step"] == [False, refused + "time_step must be a finite number of seconds from 1e-06 to 1, "
                                  "got 1e+30", True]
    assert found["readings_finite"]
    if model == "moving_cube":  # the wheel's command clamped to its URDF velocity limit
        assert all(abs(v) <= 1000.0 * 1.01 for v in found["joint_velocities"]), found
    else:  # each leg joint's command clamped to its URDF position limits, within [-1.6, 1.6]
        assert all(-1.65 <= q <= 1.65 for q in found["joint_positions"]), found
    sim.send_signal(signal.SIGINT)
    assert sim.wait(30) == 0
    output = log.read_text()
    assert "Traceback" not in output and "[ERROR]" not in output, output[-3000:]

