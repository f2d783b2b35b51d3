"""Start the longest lockstep call the sim takes, time the other services meanwhile, then stop the sim.

Usage: long_step_client.py LAUNCH_PGID. Spins the cube's wheel to its 1000 rad/s limit first (the slowest
physics: 32 PyBullet substeps per step), calls /pybullet_sim/step with MAX_STEPS in a thread, measures how
long pause_physics, get_physics_properties and list_controllers take to answer while it runs, then sends
SIGINT to the sim's roslaunch (process group LAUNCH_PGID) and reports how the step call ended. Prints one
JSON line."""
import json
import os
import signal
import sys
import threading
import time

import rospy
from std_srvs.srv import Empty

from controller_manager_msgs.srv import ListControllers
from gazebo_msgs.srv import GetPhysicsProperties
from pybullet_sim.ros.client import CommandPublisher, SimConnection
from pybullet_sim.srv import Step, StepRequest

TIMEOUT = 10.0


def main(launch_pgid: int) -> None:
    rospy.init_node("long_step_client")
    sim = SimConnection(timeout=TIMEOUT)
    wheel = CommandPublisher("/moving_cube/inertia_wheel_roll_joint_velocity_controller/command")
    wheel.wait_for_subscriber(TIMEOUT)
    wheel.publish(1.0e300)  # clamped to the URDF's 1000 rad/s
    sim.step(300, [wheel])
    others = {"/gazebo/pause_physics": rospy.ServiceProxy("/gazebo/pause_physics", Empty),
              "/gazebo/get_physics_properties": rospy.ServiceProxy("/gazebo/get_physics_properties",
                                                                   GetPhysicsProperties),
              "/moving_cube/controller_manager/list_controllers": rospy.ServiceProxy(
                  "/moving_cube/controller_manager/list_controllers", ListControllers)}
    outcome = {}

    def long_step():
        started = time.monotonic()
        try:
            rospy.ServiceProxy("/pybullet_sim/step", Step)(StepRequest(steps=StepRequest.MAX_STEPS))
            outcome["step"] = "answered"
        except (rospy.ServiceException, rospy.ROSException) as error:
            outcome["step"] = f"error: {error}"
        outcome["step_wall_s"] = time.monotonic() - started

    thread = threading.Thread(target=long_step, daemon=True)
    thread.start()
    time.sleep(0.5)  # let the long call get going: it is what is measured against
    latencies = {}
    for name, proxy in others.items():
        started = time.monotonic()
        proxy()
        latencies[name] = time.monotonic() - started
    still_stepping = thread.is_alive()
    os.killpg(launch_pgid, signal.SIGINT)  # the process group the test started
    thread.join(TIMEOUT)
    print(json.dumps({"latencies": latencies, "still_stepping": still_stepping, "returned": not thread.is_alive(),
                      **outcome}), flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]))
