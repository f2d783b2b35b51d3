"""The contact_markers node: each contact sensor's total force as an rviz arrow (visualization_msgs/Marker).

Started by rviz.launch next to rviz, never during plain training. It reads the robot's sensors from
the sim node's parameters (/pybullet_sim), so it knows no robot: for every sensor of type contact it
subscribes to its ContactsState topic and publishes on /pybullet_sim/contact_markers an arrow of the
total force on the sensor's link (the ground pushing on the hopper's foot), at most ~rate times per
wall second. The arrow starts at the link's origin when the sensor reports in the link's frame (as
the hopper's does), else at the mean contact position; it is ~meters_per_newton long per newton (the
monoped standing: 7 N, 0.35 m), at most ~max_length, and removed while the link touches nothing.

Private params: ~meters_per_newton (0.05), ~max_length (1.0 m), ~rate (30 Hz).
"""
from __future__ import annotations

import math
import sys
import time

import rospy
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker

from gazebo_msgs.msg import ContactsState

from ..config import SensorConfig, parse_robot_config
from ..errors import ConfigError
from ..names import CONTACT_MARKERS_TOPIC, SIM_NODE
from .shutdown import shutdown_on_signals, shutting_down

COLOR = ColorRGBA(1.0, 0.55, 0.0, 1.0)  # orange: apart from the robots' red, black, white and blue


def force_marker(msg: ContactsState, sensor: SensorConfig, marker_id: int, meters_per_newton: float,
                 max_length: float) -> Marker:
    """The arrow of `msg`'s total force (a DELETE marker when nothing touches)."""
    marker = Marker(header=msg.header, ns="contact_force", id=marker_id, type=Marker.ARROW)
    force = [sum(getattr(state.total_wrench.force, axis) for state in msg.states) for axis in "xyz"]
    magnitude = math.sqrt(sum(f * f for f in force))
    if magnitude == 0.0:
        marker.action = Marker.DELETE
        return marker
    if sensor.frame_id == sensor.link:
        start = Point(0.0, 0.0, 0.0)
    else:
        positions = [p for state in msg.states for p in state.contact_positions]
        start = Point(*(sum(getattr(p, axis) for p in positions) / len(positions) for axis in "xyz"))
    length = min(magnitude * meters_per_newton, max_length)
    end = Point(*(getattr(start, axis) + f / magnitude * length for axis, f in zip("xyz", force)))
    marker.action = Marker.ADD
    marker.points = [start, end]
    marker.pose.orientation.w = 1.0
    marker.scale.x, marker.scale.y, marker.scale.z = 0.03, 0.06, 0.08  # shaft and head diameters, head length
    marker.color = COLOR
    return marker


class ContactMarkers:
    def __init__(self) -> None:
        self.meters_per_newton = float(rospy.get_param("~meters_per_newton", 0.05))
        self.max_length = float(rospy.get_param("~max_length", 1.0))
        self.period = 1.0 / float(rospy.get_param("~rate", 30.0))
        if not rospy.has_param(SIM_NODE):
            raise ConfigError(f"parameter {SIM_NODE} is missing: start the robot's sim (e.g. roslaunch pybullet_sim "
                              f"cube_sim.launch rviz:=true)")
        config = parse_robot_config(rospy.get_param(SIM_NODE), where=SIM_NODE)
        self.publisher = rospy.Publisher(CONTACT_MARKERS_TOPIC, Marker, queue_size=10)
        self.last_sent: dict[int, float] = {}
        for marker_id, sensor in enumerate(s for s in config.sensors if s.type == "contact"):
            rospy.Subscriber(sensor.topic, ContactsState, self._on_contacts, callback_args=(sensor, marker_id),
                             queue_size=1)

    def _on_contacts(self, msg: ContactsState, args: tuple[SensorConfig, int]) -> None:
        sensor, marker_id = args
        now = time.monotonic()
        if now - self.last_sent.get(marker_id, -math.inf) >= self.period:
            self.last_sent[marker_id] = now
            try:
                self.publisher.publish(force_marker(msg, sensor, marker_id, self.meters_per_newton, self.max_length))
            except rospy.ROSException:  # publish() to the topic the shutdown closed while this callback ran
                if not shutting_down():
                    raise


def main() -> int:
    rospy.init_node("contact_markers", disable_signals=True)
    shutdown_on_signals()  # rospy.spin() below ends once the shutdown thread has run
    try:
        ContactMarkers()
    except ConfigError as error:
        print(f"contact_markers cannot start: {error}", file=sys.stderr, flush=True)
        return 1
    rospy.spin()
    return 0
