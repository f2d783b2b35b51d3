"""The registry of sensor kinds: everything the sim's core needs to know about each kind, in one entry.

A kind (the `type` of a sensor in config/<robot>_sim.yaml: p3d, imu, contact) names its reading type,
the World's reader, its field in pybullet_sim/Readings, how its values are packed into
pybullet_sim/PackedReadings, and whether the sim node also broadcasts the sensor link's pose on /tf.
Adding a sensor kind is one SensorKind in SENSOR_KINDS (with its reading type and World reader) and its
message type and conversions in pybullet_sim.ros.messages.SENSOR_MESSAGES. No ROS and no PyBullet here.

Packed layout (pack_readings / unpack_readings), in the order of the robot's sim config:
  values: stamp, n joints, n positions, n velocities, n efforts, then each sensor's values
  names: n joint names, then per sensor its frame_id and its kind's names
  p3d: position 3, orientation 4, linear velocity 3, angular velocity 3; names: child_frame_id
  imu: orientation 4, angular velocity 3, linear acceleration 3
  contact: number of points k, total force 3, total torque 3, then per point force 3, torque 3,
           position 3, normal 3, depth; names: the two collision names of each point
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from .readings import ContactPoint, ContactReading, ImuReading, JointStateReading, OdometryReading

SensorReading = OdometryReading | ImuReading | ContactReading
Values = Sequence[float]
Names = Sequence[str]


@dataclass(frozen=True)
class SensorKind:
    name: str                                         # the YAML type
    reading: type                                     # its pybullet_sim.readings type
    readings_field: str                               # its array in pybullet_sim/Readings
    read: Callable[[Any, Any], Any]                   # (World, SensorConfig) -> reading
    pack: Callable[[Any, list[float], list[str]], None]   # append a reading's values and names
    # (values, names, value index, name index, stamp, frame_id) -> (reading, value index, name index)
    unpack: Callable[[Values, Names, int, int, float, str], tuple[Any, int, int]]
    broadcasts_pose: bool = False                     # the sim node also puts the link's pose on /tf


def _pack_odometry(r: OdometryReading, values: list[float], names: list[str]) -> None:
    names.append(r.child_frame_id)
    values += (*r.position, *r.orientation, *r.linear_velocity, *r.angular_velocity)


def _unpack_odometry(values: Values, names: Names, i: int, k: int, stamp: float,
                     frame_id: str) -> tuple[OdometryReading, int, int]:
    reading = OdometryReading(stamp, frame_id, names[k], tuple(values[i:i + 3]), tuple(values[i + 3:i + 7]),
                              tuple(values[i + 7:i + 10]), tuple(values[i + 10:i + 13]))
    return reading, i + 13, k + 1


def _pack_imu(r: ImuReading, values: list[float], names: list[str]) -> None:
    values += (*r.orientation, *r.angular_velocity, *r.linear_acceleration)


def _unpack_imu(values: Values, names: Names, i: int, k: int, stamp: float,
                frame_id: str) -> tuple[ImuReading, int, int]:
    reading = ImuReading(stamp, frame_id, tuple(values[i:i + 4]), tuple(values[i + 4:i + 7]),
                         tuple(values[i + 7:i + 10]))
    return reading, i + 10, k


def _pack_contact(r: ContactReading, values: list[float], names: list[str]) -> None:
    values += (float(len(r.contacts)), *r.total_force, *r.total_torque)
    for point in r.contacts:
        names += (point.collision1_name, point.collision2_name)
        values += (*point.force, *point.torque, *point.position, *point.normal, point.depth)


def _unpack_contact(values: Values, names: Names, i: int, k: int, stamp: float,
                    frame_id: str) -> tuple[ContactReading, int, int]:
    count, total_force, total_torque = int(values[i]), tuple(values[i + 1:i + 4]), tuple(values[i + 4:i + 7])
    i += 7
    points = []
    for _ in range(count):
        points.append(ContactPoint(names[k], names[k + 1], tuple(values[i:i + 3]), tuple(values[i + 3:i + 6]),
                                   tuple(values[i + 6:i + 9]), tuple(values[i + 9:i + 12]), values[i + 12]))
        i, k = i + 13, k + 2
    return ContactReading(stamp, frame_id, tuple(points), total_force, total_torque), i, k


SENSOR_KINDS: dict[str, SensorKind] = {kind.name: kind for kind in (
    SensorKind("p3d", OdometryReading, "odometry", lambda world, sensor: world.read_odometry(sensor),
               _pack_odometry, _unpack_odometry, broadcasts_pose=True),
    SensorKind("imu", ImuReading, "imu", lambda world, sensor: world.read_imu(sensor), _pack_imu, _unpack_imu),
    SensorKind("contact", ContactReading, "contacts", lambda world, sensor: world.read_contact(sensor),
               _pack_contact, _unpack_contact),
)}
_KIND_OF_READING = {kind.reading: kind for kind in SENSOR_KINDS.values()}


def pack_readings(joints: JointStateReading, sensors: list[SensorReading]) -> tuple[list[float], list[str]]:
    """(values, names) of a joint state and the sensors' readings (see the layout above)."""
    values = [joints.stamp, float(len(joints.name)), *joints.position, *joints.velocity, *joints.effort]
    names = list(joints.name)
    for reading in sensors:
        names.append(reading.frame_id)
        _KIND_OF_READING[type(reading)].pack(reading, values, names)
    return values, names


def unpack_readings(values: Values, names: Names,
                    sensor_types: Sequence[str]) -> tuple[JointStateReading, list[SensorReading]]:
    """The readings pack_readings packed, for sensors of `sensor_types` (kind names, e.g. "p3d", "imu",
    "contact") in order; ValueError if the numbers do not fit them."""
    try:
        stamp, n = values[0], int(values[1])
        i, k = 2 + 3 * n, n
        joints = JointStateReading(stamp, tuple(names[:n]), tuple(values[2:2 + n]), tuple(values[2 + n:2 + 2 * n]),
                                   tuple(values[2 + 2 * n:i]))
        sensors: list[SensorReading] = []
        for kind in sensor_types:
            if kind not in SENSOR_KINDS:
                raise ValueError(f"unknown sensor type {kind!r}")
            reading, i, k = SENSOR_KINDS[kind].unpack(values, names, i, k + 1, stamp, names[k])
            sensors.append(reading)
    except IndexError:
        raise ValueError(f"packed readings too short for joints and sensors {', '.join(sensor_types)}") from None
    if i != len(values) or k != len(names):
        raise ValueError(f"packed readings hold {len(values) - i} numbers and {len(names) - k} names more than "
                         f"joints and sensors {', '.join(sensor_types)} need")
    return joints, sensors
