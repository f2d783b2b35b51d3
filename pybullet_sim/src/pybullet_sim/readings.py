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


# -- packed readings: every sensor as numbers and names (pybullet_sim/PackedReadings) -------------
# The lockstep answer for clients that want readings rather than messages: the same values, exact
# float64, without building, serialising and parsing a message per sensor. Layout, in the order of the
# robot's sim config (the sensor types are the key to read it back):
#   values: stamp, n joints, n positions, n velocities, n efforts, then per sensor
#     p3d: position 3, orientation 4, linear velocity 3, angular velocity 3
#     imu: orientation 4, angular velocity 3, linear acceleration 3
#     contact: number of points k, total force 3, total torque 3, then per point force 3, torque 3,
#              position 3, normal 3, depth
#   names: n joint names, then per sensor its frame_id (p3d: and child_frame_id; contact: and the two
#          collision names of each point)
SensorReadingType = OdometryReading | ImuReading | ContactReading


def pack_readings(joints: JointStateReading, sensors: list[SensorReadingType]) -> tuple[list[float], list[str]]:
    """(values, names) of a joint state and the sensors' readings (see the layout above)."""
    values = [joints.stamp, float(len(joints.name)), *joints.position, *joints.velocity, *joints.effort]
    names = list(joints.name)
    for reading in sensors:
        names.append(reading.frame_id)
        if isinstance(reading, OdometryReading):
            names.append(reading.child_frame_id)
            values += (*reading.position, *reading.orientation, *reading.linear_velocity, *reading.angular_velocity)
        elif isinstance(reading, ImuReading):
            values += (*reading.orientation, *reading.angular_velocity, *reading.linear_acceleration)
        else:
            values += (float(len(reading.contacts)), *reading.total_force, *reading.total_torque)
            for point in reading.contacts:
                names += (point.collision1_name, point.collision2_name)
                values += (*point.force, *point.torque, *point.position, *point.normal, point.depth)
    return values, names


def unpack_readings(values, names, sensor_types) -> tuple[JointStateReading, list[SensorReadingType]]:
    """The readings pack_readings packed, for sensors of `sensor_types` ("p3d", "imu", "contact") in
    order; ValueError if the numbers do not fit them."""
    try:
        stamp, n = values[0], int(values[1])
        i, k = 2 + 3 * n, n
        joints = JointStateReading(stamp, tuple(names[:n]), tuple(values[2:2 + n]), tuple(values[2 + n:2 + 2 * n]),
                                   tuple(values[2 + 2 * n:i]))
        sensors: list[SensorReadingType] = []
        for kind in sensor_types:
            frame_id = names[k]
            k += 1
            if kind == "p3d":
                sensors.append(OdometryReading(stamp, frame_id, names[k], tuple(values[i:i + 3]),
                                               tuple(values[i + 3:i + 7]), tuple(values[i + 7:i + 10]),
                                               tuple(values[i + 10:i + 13])))
                i, k = i + 13, k + 1
            elif kind == "imu":
                sensors.append(ImuReading(stamp, frame_id, tuple(values[i:i + 4]), tuple(values[i + 4:i + 7]),
                                          tuple(values[i + 7:i + 10])))
                i += 10
            elif kind == "contact":
                count, total_force = int(values[i]), tuple(values[i + 1:i + 4])
                total_torque = tuple(values[i + 4:i + 7])
                i += 7
                points = []
                for _ in range(count):
                    points.append(ContactPoint(names[k], names[k + 1], tuple(values[i:i + 3]),
                                               tuple(values[i + 3:i + 6]), tuple(values[i + 6:i + 9]),
                                               tuple(values[i + 9:i + 12]), values[i + 12]))
                    i, k = i + 13, k + 2
                sensors.append(ContactReading(stamp, frame_id, tuple(points), total_force, total_torque))
            else:
                raise ValueError(f"unknown sensor type {kind!r}")
    except IndexError:
        raise ValueError(f"packed readings too short for joints and sensors {', '.join(sensor_types)}") from None
    if i != len(values) or k != len(names):
        raise ValueError(f"packed readings hold {len(values) - i} numbers and {len(names) - k} names more than "
                         f"joints and sensors {', '.join(sensor_types)} need")
    return joints, sensors
