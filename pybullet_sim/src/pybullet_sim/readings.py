"""Sensor readings as plain data: what the World measures and what robot interfaces hand to task envs.

These dataclasses carry no ROS types, so the same task code runs over ROS (readings rebuilt from
messages) and in-process (readings straight from a World).
"""
from __future__ import annotations

from dataclasses import dataclass, field

Vector3 = tuple[float, ...]      # x, y, z
Quaternion = tuple[float, ...]   # x, y, z, w (ROS order)


@dataclass(frozen=True)
class JointStateReading:
    """sensor_msgs/JointState: one entry per movable joint, in URDF order."""

    stamp: float
    name: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]


@dataclass(frozen=True)
class OdometryReading:
    """nav_msgs/Odometry as gazebo_ros_p3d publishes it: pose and twist in `frame_id` (world)."""

    stamp: float
    frame_id: str
    child_frame_id: str
    position: Vector3
    orientation: Quaternion
    linear_velocity: Vector3
    angular_velocity: Vector3


@dataclass(frozen=True)
class ImuReading:
    """sensor_msgs/Imu as gazebo_ros_imu publishes it: world orientation, body-frame rates and
    body-frame proper acceleration (reads +9.81 on z when standing still)."""

    stamp: float
    frame_id: str
    orientation: Quaternion
    angular_velocity: Vector3
    linear_acceleration: Vector3


@dataclass(frozen=True)
class ContactPoint:
    """One touching pair, force and torque on collision1 expressed in the reading's frame."""

    collision1_name: str
    collision2_name: str
    force: Vector3
    torque: Vector3
    position: Vector3
    normal: Vector3
    depth: float


@dataclass(frozen=True)
class ContactReading:
    """gazebo_msgs/ContactsState as gazebo_ros_bumper publishes it; `contacts` is empty in the air."""

    stamp: float
    frame_id: str
    contacts: tuple[ContactPoint, ...] = field(default_factory=tuple)
    total_force: Vector3 = (0.0, 0.0, 0.0)
    total_torque: Vector3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class FrameState:
    """Pose and twist of a link's URDF frame in the world frame, as Gazebo's get_model_state and
    get_link_state report them: the linear velocity is that of the frame's origin."""

    position: Vector3
    orientation: Quaternion
    linear_velocity: Vector3
    angular_velocity: Vector3
