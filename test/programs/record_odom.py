"""Drive the cube sim in lockstep with a fixed command sequence and print its odom stream as JSON.

Used by the determinism tests: two fresh sims with the same ~seed must print the same stream."""
import json
import sys

import rospy
from nav_msgs.msg import Odometry

from pybullet_sim.ros import messages
from pybullet_sim.ros.client import CommandPublisher, SensorSubscriber, SimConnection

TIMEOUT = 10.0


def main(cycles: int) -> None:
    rospy.init_node("record_odom")
    sim = SimConnection(timeout=TIMEOUT)
    wheel = CommandPublisher("/moving_cube/inertia_wheel_roll_joint_velocity_controller/command")
    wheel.wait_for_subscriber(TIMEOUT)
    odom = SensorSubscriber("/moving_cube/odom", Odometry, messages.odometry_reading)
    odom.wait_for_connection(TIMEOUT)
    stream = []
    for k in range(cycles):
        wheel.publish(100.0 if (k // 25) % 2 == 0 else -100.0)
        mark = odom.count
        stamp = sim.step(20, [wheel])
        reading = odom.wait_newer(mark, TIMEOUT, stamp)
        stream.append([reading.stamp, *reading.position, *reading.orientation, *reading.linear_velocity])
    print(json.dumps(stream))


if __name__ == "__main__":
    main(int(rospy.myargv(sys.argv)[1]))
