"""Conversions between readings (plain data) and ROS messages, both ways, and each sensor kind's message.

The sim node turns World readings into messages; ROS robot interfaces turn received messages back
into the same readings, so task envs never see a message type. SENSOR_MESSAGES gives each sensor kind
of pybullet_sim.sensors.SENSOR_KINDS, by its name, its message type and conversions.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import rospy
from geometry_msgs.msg import Pose, TransformStamped, Twist, Vector3, Wrench
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Image, Imu, JointState

from controller_manager_msgs.msg import ControllerState, HardwareInterfaceResources
from gazebo_msgs.msg import ContactsState, ContactState, ODEPhysics

from ..controller_manager import ControllerInfo
from ..physics_properties import OdeConfig
from ..readings import ContactPoint, ContactReading, FrameState, ImuReading, JointStateReading, OdometryReading


def _vector(values) -> Vector3:
    return Vector3(values[0], values[1], values[2])


def _tuple3(v) -> tuple:
    return (v.x, v.y, v.z)


def _quaternion_tuple(q) -> tuple:
    return (q.x, q.y, q.z, q.w)


def joint_state_msg(reading: JointStateReading, stamp: rospy.Time) -> JointState:
    msg = JointState(name=list(reading.name), position=list(reading.position),
                     velocity=list(reading.velocity), effort=list(reading.effort))
    msg.header.stamp = stamp
    return msg


def odometry_msg(reading: OdometryReading, stamp: rospy.Time) -> Odometry:
    msg = Odometry()
    msg.header.stamp = stamp
    msg.header.frame_id = reading.frame_id
    msg.child_frame_id = reading.child_frame_id
    pose = msg.pose.pose
    pose.position.x, pose.position.y, pose.position.z = reading.position
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = reading.orientation
    msg.twist.twist.linear = _vector(reading.linear_velocity)
    msg.twist.twist.angular = _vector(reading.angular_velocity)
    return msg


def imu_msg(reading: ImuReading, stamp: rospy.Time) -> Imu:
    msg = Imu()
    msg.header.stamp = stamp
    msg.header.frame_id = reading.frame_id
    o = msg.orientation
    o.x, o.y, o.z, o.w = reading.orientation
    msg.angular_velocity = _vector(reading.angular_velocity)
    msg.linear_acceleration = _vector(reading.linear_acceleration)
    return msg


def contacts_msg(reading: ContactReading, stamp: rospy.Time) -> ContactsState:
    msg = ContactsState()
    msg.header.stamp = stamp
    msg.header.frame_id = reading.frame_id
    if reading.contacts:
        # Gazebo's bumper groups the points of one collision pair into one ContactState.
        state = ContactState(info=f"Debug: i:(0/1) my geom:{reading.contacts[0].collision1_name}",
                             collision1_name=reading.contacts[0].collision1_name,
                             collision2_name=reading.contacts[0].collision2_name)
        for point in reading.contacts:
            state.wrenches.append(Wrench(force=_vector(point.force), torque=_vector(point.torque)))
            state.contact_positions.append(_vector(point.position))
            state.contact_normals.append(_vector(point.normal))
            state.depths.append(point.depth)
        state.total_wrench = Wrench(force=_vector(reading.total_force), torque=_vector(reading.total_torque))
        msg.states.append(state)
    return msg


def image_msg(rgb: np.ndarray, stamp: rospy.Time) -> Image:
    """An HxWx3 uint8 RGB array as a sensor_msgs/Image (encoding rgb8)."""
    height, width, _ = rgb.shape
    msg = Image(height=height, width=width, encoding="rgb8", is_bigendian=0, step=3 * width, data=rgb.tobytes())
    msg.header.stamp = stamp
    return msg


def image_array(msg: Image) -> np.ndarray:
    """An rgb8 sensor_msgs/Image as an HxWx3 uint8 array."""
    if msg.encoding != "rgb8" or msg.step != 3 * msg.width:
        raise ValueError(f"expected an rgb8 image without row padding, got {msg.encoding} with step {msg.step} for "
                         f"width {msg.width}")
    return np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.width, 3).copy()


def transform_msg(parent: str, child: str, position, orientation, stamp: rospy.Time) -> TransformStamped:
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = parent
    msg.child_frame_id = child
    t = msg.transform.translation
    t.x, t.y, t.z = position
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = orientation
    return msg


def joint_state_reading(msg: JointState) -> JointStateReading:
    return JointStateReading(stamp=msg.header.stamp.to_sec(), name=tuple(msg.name), position=tuple(msg.position),
                             velocity=tuple(msg.velocity), effort=tuple(msg.effort))


def odometry_reading(msg: Odometry) -> OdometryReading:
    return OdometryReading(stamp=msg.header.stamp.to_sec(), frame_id=msg.header.frame_id,
                           child_frame_id=msg.child_frame_id, position=_tuple3(msg.pose.pose.position),
                           orientation=_quaternion_tuple(msg.pose.pose.orientation),
                           linear_velocity=_tuple3(msg.twist.twist.linear),
                           angular_velocity=_tuple3(msg.twist.twist.angular))


def imu_reading(msg: Imu) -> ImuReading:
    return ImuReading(stamp=msg.header.stamp.to_sec(), frame_id=msg.header.frame_id,
                      orientation=_quaternion_tuple(msg.orientation),
                      angular_velocity=_tuple3(msg.angular_velocity),
                      linear_acceleration=_tuple3(msg.linear_acceleration))


def contact_reading(msg: ContactsState) -> ContactReading:
    points = []
    total_force, total_torque = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    for state in msg.states:
        for wrench, position, normal, depth in zip(state.wrenches, state.contact_positions,
                                                   state.contact_normals, state.depths):
            points.append(ContactPoint(state.collision1_name, state.collision2_name, _tuple3(wrench.force),
                                       _tuple3(wrench.torque), _tuple3(position), _tuple3(normal), depth))
        total_force = _tuple3(state.total_wrench.force)
        total_torque = _tuple3(state.total_wrench.torque)
    return ContactReading(stamp=msg.header.stamp.to_sec(), frame_id=msg.header.frame_id, contacts=tuple(points),
                          total_force=total_force, total_torque=total_torque)


def pose_twist_msgs(state: FrameState) -> tuple:
    """A FrameState as (geometry_msgs/Pose, geometry_msgs/Twist)."""
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = state.position
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = state.orientation
    return pose, Twist(linear=_vector(state.linear_velocity), angular=_vector(state.angular_velocity))


def frame_state(pose: Pose, twist: Twist) -> FrameState:
    return FrameState(_tuple3(pose.position), _quaternion_tuple(pose.orientation), _tuple3(twist.linear),
                      _tuple3(twist.angular))


def ode_config(msg: ODEPhysics) -> OdeConfig:
    return OdeConfig(**{name: getattr(msg, name) for name in ODEPhysics.__slots__})


def ode_physics_msg(config: OdeConfig) -> ODEPhysics:
    return ODEPhysics(**{name: getattr(config, name) for name in ODEPhysics.__slots__})


def controller_state_msg(info: ControllerInfo) -> ControllerState:
    return ControllerState(name=info.name, state=info.state, type=info.type, claimed_resources=[
        HardwareInterfaceResources(hardware_interface=info.hardware_interface, resources=list(info.resources))])


@dataclass(frozen=True)
class MessageSide:
    """A sensor kind's ROS message type and its conversions: reading -> message (stamped) and message -> reading."""

    type: type
    to_message: Callable[[Any, Any], Any]
    to_reading: Callable[[Any], Any]


SENSOR_MESSAGES: dict[str, MessageSide] = {  # by the kind's name, as pybullet_sim.sensors.SENSOR_KINDS
    "p3d": MessageSide(Odometry, odometry_msg, odometry_reading),
    "imu": MessageSide(Imu, imu_msg, imu_reading),
    "contact": MessageSide(ContactsState, contacts_msg, contact_reading),
}
