"""What the World measures: its sensors as Gazebo's plugins read them (p3d odometry, IMU, contact), and
the model and link states of Gazebo's get_model_state and get_link_state.

A mixin of pybullet_sim.world.World, apart from its physics and controllers; each sensor kind's reader
here is named in pybullet_sim.sensors' registry. No ROS here.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pybullet as p

from .config import SensorConfig
from .readings import ContactPoint, ContactReading, FrameState, ImuReading, OdometryReading
from .transforms import cross, quaternion_multiply, rotate, transpose_rotate

GROUND_COLLISION_NAME = "ground_plane::link::collision"


class Measurements:
    """The World's readers; the World holds the attributes declared here."""

    robot_name: str
    _cid: int
    _body: int
    _plane: int
    _link_index: dict[str, int]
    _rng: np.random.Generator
    _gravity: tuple[float, float, float]
    _imu_previous: dict[str, tuple[float, tuple[float, float, float]]]
    _time_ns: int

    @property
    def time(self) -> float:
        """Simulated seconds since the start or the last reset_simulation."""
        return self._time_ns / 1e9

    def _link_pose_twist(self, link: str) -> tuple[Any, Any, Any, Any]:
        """A link's (position, orientation, linear, angular velocity) in the world, as PyBullet gives them: a
        child link's URDF frame pose and centre-of-mass velocity, the base's centre of mass."""
        index, cid = self._link_index[link], self._cid
        if index == -1:
            position, orientation = p.getBasePositionAndOrientation(self._body, physicsClientId=cid)
            linear, angular = p.getBaseVelocity(self._body, physicsClientId=cid)
        else:
            state = p.getLinkState(self._body, index, computeLinkVelocity=1, computeForwardKinematics=1,
                                   physicsClientId=cid)
            position, orientation, linear, angular = state[4], state[5], state[6], state[7]
        return position, orientation, linear, angular

    def read_odometry(self, sensor: SensorConfig) -> OdometryReading:
        position, orientation, linear, angular = self._link_pose_twist(sensor.link)
        sigma = sensor.gaussian_noise
        if sigma > 0.0:
            noise = self._rng.normal(0.0, sigma, 12).tolist()
            position = tuple(v + n for v, n in zip(position, noise[0:3]))
            rpy = p.getEulerFromQuaternion(orientation)
            orientation = p.getQuaternionFromEuler([v + n for v, n in zip(rpy, noise[3:6])])
            linear = tuple(v + n for v, n in zip(linear, noise[6:9]))
            angular = tuple(v + n for v, n in zip(angular, noise[9:12]))
        return OdometryReading(stamp=self.time, frame_id=sensor.frame_id, child_frame_id=sensor.link,
                               position=tuple(position), orientation=tuple(orientation),
                               linear_velocity=tuple(linear), angular_velocity=tuple(angular))

    def read_imu(self, sensor: SensorConfig) -> ImuReading:
        _, orientation, linear, angular = self._link_pose_twist(sensor.link)
        now = self.time
        previous = self._imu_previous.get(sensor.name)
        if previous is not None and now > previous[0]:
            dt = now - previous[0]
            acceleration = [(v - v0) / dt for v, v0 in zip(linear, previous[1])]
        else:
            acceleration = [0.0, 0.0, 0.0]
        self._imu_previous[sensor.name] = (now, tuple(linear))
        proper = [a - g for a, g in zip(acceleration, self._gravity, strict=True)]
        angular_body = transpose_rotate(orientation, angular)
        proper_body = transpose_rotate(orientation, proper)
        sigma = sensor.gaussian_noise
        if sigma > 0.0:
            noise = self._rng.normal(0.0, sigma, 6).tolist()
            angular_body = tuple(v + n for v, n in zip(angular_body, noise[0:3]))
            proper_body = tuple(v + n for v, n in zip(proper_body, noise[3:6]))
        return ImuReading(stamp=now, frame_id=sensor.frame_id, orientation=tuple(orientation),
                          angular_velocity=tuple(angular_body), linear_acceleration=tuple(proper_body))

    def read_contact(self, sensor: SensorConfig) -> ContactReading:
        index, cid = self._link_index[sensor.link], self._cid
        points = p.getContactPoints(bodyA=self._body, linkIndexA=index, physicsClientId=cid)
        if not points:
            return ContactReading(stamp=self.time, frame_id=sensor.frame_id)
        origin, orientation, _, _ = self._link_pose_twist(sensor.link)
        in_link_frame = sensor.frame_id == sensor.link
        own_name = f"{self.robot_name}::{sensor.link}::{sensor.link}_collision"
        contacts = []
        total_force: tuple[float, ...] = (0.0, 0.0, 0.0)
        total_torque: tuple[float, ...] = (0.0, 0.0, 0.0)
        for point in points:
            normal, normal_force = point[7], point[9]
            f1, d1, f2, d2 = point[10], point[11], point[12], point[13]
            force = tuple(normal_force * n + f1 * a + f2 * b for n, a, b in zip(normal, d1, d2))
            position = point[5]
            torque = cross(tuple(c - o for c, o in zip(position, origin)), force)
            total_force = tuple(t + f for t, f in zip(total_force, force))
            total_torque = tuple(t + q for t, q in zip(total_torque, torque))
            other = (GROUND_COLLISION_NAME if point[2] == self._plane
                     else f"{self.robot_name}::link{point[4]}::collision")
            if in_link_frame:
                force, torque, normal = (transpose_rotate(orientation, v) for v in (force, torque, normal))
            contacts.append(ContactPoint(collision1_name=own_name, collision2_name=other, force=force,
                                         torque=torque, position=tuple(position), normal=tuple(normal),
                                         depth=-point[8]))
        if in_link_frame:
            total_force = transpose_rotate(orientation, total_force)
            total_torque = transpose_rotate(orientation, total_torque)
        return ContactReading(stamp=self.time, frame_id=sensor.frame_id, contacts=tuple(contacts),
                              total_force=total_force, total_torque=total_torque)

    # -- model and link states (Gazebo's get_model_state, get_link_state) ---------------------------
    @property
    def link_names(self) -> tuple[str, ...]:
        """Every link of the robot, the base first."""
        return tuple(self._link_index)

    def model_state(self) -> FrameState:
        """The robot's pose and twist: those of its base link's URDF frame."""
        return self.link_state(self.link_names[0])

    def link_name(self, name: str) -> str:
        """The link a Gazebo name means: scoped ("moving_cube::cube_body") or not; ValueError naming it if none."""
        model, separator, link = name.rpartition("::")
        if (not separator or model == self.robot_name) and link in self._link_index:
            return link
        raise ValueError(f"{self.robot_name} has no link {name!r} (links: "
                         f"{', '.join(f'{self.robot_name}::{link}' for link in self.link_names)})")

    def entity_state(self, name: str) -> FrameState:
        """The state of what a Gazebo entity name means here: the model (robot name) or one of its links."""
        return self.model_state() if name == self.robot_name else self.link_state(self.link_name(name))

    def link_state(self, link: str) -> FrameState:
        """Pose and twist of a link's URDF frame in the world; ValueError naming the link if there is none."""
        if link not in self._link_index:
            raise ValueError(f"{self.robot_name} has no link {link!r} (links: {', '.join(self.link_names)})")
        index, body, cid = self._link_index[link], self._body, self._cid
        if index == -1:  # PyBullet's base pose is its centre of mass; the link frame may be offset from it
            com, com_orientation = p.getBasePositionAndOrientation(body, physicsClientId=cid)
            com_velocity, angular = p.getBaseVelocity(body, physicsClientId=cid)
            inertial_position, inertial_orientation = p.getDynamicsInfo(body, -1, physicsClientId=cid)[3:5]
            x, y, z, w = inertial_orientation
            orientation = quaternion_multiply(com_orientation, (-x, -y, -z, w))
            position = tuple(c - o for c, o in zip(com, rotate(orientation, inertial_position), strict=True))
        else:
            state = p.getLinkState(body, index, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=cid)
            com, position, orientation, com_velocity, angular = state[0], state[4], state[5], state[6], state[7]
        offset = tuple(a - b for a, b in zip(position, com, strict=True))
        linear = tuple(v + w for v, w in zip(com_velocity, cross(angular, offset), strict=True))
        return FrameState(tuple(position), tuple(orientation), linear, tuple(angular))

    def link_pose(self, link: str):
        """Noise-free world pose of a link's URDF frame."""
        position, orientation, _, _ = self._link_pose_twist(link)
        return tuple(position), tuple(orientation)

