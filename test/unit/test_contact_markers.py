"""The contact_markers node's arrow for a ContactsState (pure: no master); the node itself runs in
test/integration/test_rendering_over_ros.py."""
import math

import pytest
from geometry_msgs.msg import Vector3, Wrench
from visualization_msgs.msg import Marker

from gazebo_msgs.msg import ContactsState, ContactState
from pybullet_sim.config import SensorConfig
from pybullet_sim.ros.markers import force_marker

IN_LINK_FRAME = SensorConfig(name="foot", type="contact", link="foot", topic="/foot", frame_id="foot", update_rate=1)
IN_WORLD = SensorConfig(name="foot", type="contact", link="foot", topic="/foot", frame_id="world", update_rate=1)


def contacts(frame_id: str, force: tuple, positions: list) -> ContactsState:
    msg = ContactsState()
    msg.header.frame_id = frame_id
    if positions:
        msg.states.append(ContactState(total_wrench=Wrench(force=Vector3(*force)),
                                       contact_positions=[Vector3(*p) for p in positions]))
    return msg


def tip(marker: Marker) -> tuple:
    return tuple(getattr(marker.points[1], axis) for axis in "xyz")


def test_the_arrow_starts_at_the_link_and_points_along_the_force():
    marker = force_marker(contacts("foot", (0.0, 3.0, 4.0), [(9.0, 9.0, 0.0)]), IN_LINK_FRAME, 2, 0.01, 1.0)
    assert (marker.action, marker.type, marker.id, marker.header.frame_id) == (Marker.ADD, Marker.ARROW, 2, "foot")
    assert (marker.points[0].x, marker.points[0].y, marker.points[0].z) == (0.0, 0.0, 0.0)
    assert tip(marker) == pytest.approx((0.0, 0.03, 0.04))  # 5 N at 0.01 m/N
    assert marker.color.a == 1.0 and marker.scale.x > 0.0


def test_a_world_frame_arrow_starts_at_the_mean_contact_and_is_clipped():
    marker = force_marker(contacts("world", (0.0, 0.0, 500.0), [(1.0, 0.0, 0.0), (3.0, 2.0, 0.0)]), IN_WORLD, 0,
                          0.01, 1.0)
    assert (marker.points[0].x, marker.points[0].y, marker.points[0].z) == (2.0, 1.0, 0.0)
    assert tip(marker) == pytest.approx((2.0, 1.0, 1.0))  # 5 m clipped to max_length 1 m
    assert math.dist((2.0, 1.0, 0.0), tip(marker)) == pytest.approx(1.0)


def test_no_contact_removes_the_arrow():
    assert force_marker(contacts("foot", (0.0, 0.0, 0.0), []), IN_LINK_FRAME, 0, 0.01, 1.0).action == Marker.DELETE
