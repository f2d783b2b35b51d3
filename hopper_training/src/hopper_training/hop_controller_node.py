"""The hop_controller node: hopper_training.controller.core on the tutorial's topics, for a free-running sim.

Subscribes to the monoped's sensors as the tutorial named them (/monoped/joint_states, /monoped/imu/data,
/odom, /lowerleg_contactsensor_state) and publishes ONLY the three position commands
(/monoped/{haa,hfe,kfe}_joint_position_controller/command). On each joint_states message at least
~control_period of sim time after the last command, it runs the controller on the latest message of
every sensor and publishes the three targets. A sim reset (time going back) restarts the controller.

The sim must run freely: the controller needs a command every 1-5 ms of sim time
(docs/research/2026-11-25-hop-stages.md), so a real_time_factor below 1 gives a Python node the wall time to
keep up (hop_controller.launch: 0.25). With ~unpause the node starts a paused sim itself, once the sim
subscribes to its commands and publishes every sensor it reads: a sim that ran before then let the monoped
land uncontrolled for the 50-150 ms the node took to connect, and from there it fell in 4 runs of 8 on a
busy machine (0 of 8 with the connected start).

Private params: ~speed_x, ~speed_y (m/s commanded along the body's heading and to its left, default 0),
~control_period (s of sim time, default 0.001), ~apex_target (m, default 0: a fixed thrust), ~unpause
(default false: call /gazebo/unpause_physics once connected), ~connect_timeout (wall s, default 60).
"""
from __future__ import annotations

import sys
import threading
import time

import rospy
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64
from std_srvs.srv import Empty

from gazebo_msgs.msg import ContactsState
from pybullet_sim.readings import ContactReading, ImuReading, OdometryReading
from pybullet_sim.ros.messages import contact_reading, imu_reading, joint_state_reading, odometry_reading
from pybullet_sim.ros.shutdown import shutdown_on_signals

from .controller.core import HopController, HopGains, hop_input

JOINT_STATES = "/monoped/joint_states"
IMU = "/monoped/imu/data"
ODOMETRY = "/odom"
CONTACT = "/lowerleg_contactsensor_state"
COMMANDS = tuple(f"/monoped/{joint}_joint_position_controller/command" for joint in ("haa", "hfe", "kfe"))
UNPAUSE = "/gazebo/unpause_physics"


class HopControllerNode:
    """Keeps the latest reading of each sensor; runs the controller on joint_states."""

    def __init__(self, controller: HopController, control_period: float):
        self.controller = controller
        self.control_period = control_period
        self._lock = threading.Lock()
        self._imu: ImuReading | None = None
        self._odometry: OdometryReading | None = None
        self._contact: ContactReading | None = None
        self._last_control = -float("inf")
        self._publishers = [rospy.Publisher(topic, Float64, queue_size=1, tcp_nodelay=True) for topic in COMMANDS]
        self._subscribers = [
            rospy.Subscriber(IMU, Imu, self._on_imu, queue_size=1, tcp_nodelay=True),
            rospy.Subscriber(ODOMETRY, Odometry, self._on_odometry, queue_size=1, tcp_nodelay=True),
            rospy.Subscriber(CONTACT, ContactsState, self._on_contact, queue_size=1, tcp_nodelay=True),
            rospy.Subscriber(JOINT_STATES, JointState, self._on_joint_states, queue_size=1, tcp_nodelay=True)]

    def unconnected(self) -> list[str]:
        """The command topics no one subscribes to and the sensor topics no one publishes to this node."""
        return [topic.resolved_name for topic in (*self._publishers, *self._subscribers)
                if topic.get_num_connections() == 0]

    def unpause_when_connected(self, timeout: float) -> None:
        """Waits (at most `timeout` wall s) until every topic of the node is connected, then unpauses the sim."""
        deadline = time.monotonic() + timeout
        while missing := self.unconnected():
            if time.monotonic() > deadline:
                raise TimeoutError(f"no connection on {', '.join(missing)} within {timeout} s: is the monoped's "
                                   "sim running (hop_controller.launch starts it unless sim:=false)?")
            time.sleep(0.01)  # bounded poll of rospy's connection counts
        try:
            rospy.wait_for_service(UNPAUSE, max(deadline - time.monotonic(), 1.0))
        except rospy.ROSException:
            raise TimeoutError(f"{UNPAUSE} was not offered within {timeout} s: is the sim node up?") from None
        rospy.ServiceProxy(UNPAUSE, Empty)()

    def _on_imu(self, msg: Imu) -> None:
        self._imu = imu_reading(msg)

    def _on_odometry(self, msg: Odometry) -> None:
        self._odometry = odometry_reading(msg)

    def _on_contact(self, msg: ContactsState) -> None:
        self._contact = contact_reading(msg)

    def _on_joint_states(self, msg: JointState) -> None:
        joints = joint_state_reading(msg)
        imu, odometry, contact = self._imu, self._odometry, self._contact
        if imu is None or odometry is None or contact is None:
            return
        with self._lock:
            if joints.stamp < self._last_control:  # the sim was reset
                self.controller.reset()
                self._last_control = -float("inf")
            if joints.stamp - self._last_control < self.control_period - 1e-6:
                return
            self._last_control = joints.stamp
            targets = self.controller.update(hop_input(joints, imu, odometry, contact))
        for publisher, target in zip(self._publishers, targets, strict=True):
            publisher.publish(Float64(target))


def main() -> int:
    rospy.init_node("hop_controller", disable_signals=True)
    shutdown_on_signals()
    speed = (float(rospy.get_param("~speed_x", 0.0)), float(rospy.get_param("~speed_y", 0.0)))
    control_period = float(rospy.get_param("~control_period", 0.001))
    apex_target = float(rospy.get_param("~apex_target", 0.0))
    connect_timeout = float(rospy.get_param("~connect_timeout", 60.0))
    if not control_period > 0.0:
        rospy.logfatal(f"hop_controller cannot start: ~control_period must be > 0 s, got {control_period}")
        return 1
    node = HopControllerNode(HopController(HopGains(speed=speed, apex_target=apex_target)), control_period)
    rospy.loginfo(f"hop_controller: speed {speed} m/s, a command every {control_period} s of sim time")
    if rospy.get_param("~unpause", False):
        try:
            node.unpause_when_connected(connect_timeout)
        except TimeoutError as error:
            rospy.logfatal(f"hop_controller cannot start the sim: {error}")
            return 1
        rospy.loginfo(f"hop_controller: connected, {UNPAUSE} called")
    rospy.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
