"""The physics world that stands in for Gazebo: PyBullet plus ros_control-style controllers and sensors.

No ROS here: a World loads a URDF and a RobotConfig, advances time in fixed physics steps, and hands
out plain readings (pybullet_sim.readings). The sim node wraps it for ROS; task envs can also drive
it in-process (the "direct" backend) with the same results.

Semantics kept from Gazebo + ros_control:
- effort_controllers/JointVelocityController and JointPositionController are effort PIDs evaluated
  every physics step; the effort is clamped to the URDF effort limit, as gazebo_ros_control does.
- p3d odometry adds seeded Gaussian noise to position, orientation (as roll/pitch/yaw), and both
  velocities; pose and twist are in the world frame.
- The IMU reports world orientation, body-frame angular velocity and body-frame proper acceleration.
- The contact sensor reports the touching pairs of one link; no contacts means an empty list.
- reset_world restores poses, velocities and controllers; reset_simulation also sets time back to 0
  and restarts the noise generator from the seed.
"""
from __future__ import annotations

import math
import os
import tempfile
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import pybullet as p

from .config import ConfigError, JointControllerConfig, RobotConfig, SensorConfig
from .readings import (ContactPoint, ContactReading, ImuReading, JointStateReading, OdometryReading)

GRAVITY = (0.0, 0.0, -9.81)
MAX_IMAGE_SIZE = 4096  # pixels per side of a rendered image
GROUND_COLLISION_NAME = "ground_plane::link::collision"


class UrdfError(ValueError):
    """The robot description is missing, not XML, or not a URDF PyBullet can load."""


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    type: str


def parse_urdf_joints(urdf_text: str, source: str) -> Tuple[str, Dict[str, UrdfJoint]]:
    """Return the robot name and its joints by name; raise UrdfError naming `source` if it is not a URDF."""
    if not urdf_text or not urdf_text.strip():
        raise UrdfError(f"{source} is empty")
    try:
        root = ElementTree.fromstring(urdf_text)
    except ElementTree.ParseError as error:
        raise UrdfError(f"{source} is not valid XML: {error}") from None
    if root.tag != "robot" or not root.get("name"):
        raise UrdfError(f"{source} is not a URDF: the root element must be <robot name=...>, got <{root.tag}>")
    if root.find("link") is None:
        raise UrdfError(f"{source} is not a URDF: it has no <link>")
    joints = {j.get("name"): UrdfJoint(j.get("name"), j.get("type")) for j in root.findall("joint")}
    return root.get("name"), joints


def _transpose_rotate(quaternion: Sequence[float], vector: Sequence[float]) -> Tuple[float, float, float]:
    """Express a world-frame vector in the frame whose world orientation is `quaternion`."""
    m = p.getMatrixFromQuaternion(quaternion)
    x, y, z = vector
    return (m[0] * x + m[3] * y + m[6] * z, m[1] * x + m[4] * y + m[7] * z, m[2] * x + m[5] * y + m[8] * z)


def _cross(a: Sequence[float], b: Sequence[float]) -> Tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


class _EffortPid:
    """One ros_control effort PID (control_toolbox::Pid) on one joint."""

    def __init__(self, config: JointControllerConfig, joint_index: int, effort_limit: float,
                 lower: float, upper: float, continuous: bool):
        self.config = config
        self.joint_index = joint_index
        self.effort_limit = effort_limit
        self.lower, self.upper = lower, upper
        self.has_limits = not continuous and lower < upper
        self.continuous = continuous
        self.is_position = config.is_position
        gains = config.pid
        self.p, self.i, self.d, self.i_clamp = gains.p, gains.i, gains.d, gains.i_clamp
        self.command = 0.0
        self._integral = 0.0
        self._previous_error = 0.0

    def reset(self, position: float) -> None:
        """Controller (re)start: a position controller holds the current position, a velocity one stops."""
        self.command = position if self.is_position else 0.0
        self._integral = 0.0
        self._previous_error = 0.0

    def effort(self, position: float, velocity: float, dt: float) -> float:
        if self.is_position:
            target = min(max(self.command, self.lower), self.upper) if self.has_limits else self.command
            error = target - position
            if self.continuous:
                error = math.remainder(error, 2.0 * math.pi)
            error_dot = -velocity
        else:
            error = self.command - velocity
            error_dot = (error - self._previous_error) / dt
            self._previous_error = error
        if self.i_clamp > 0.0:
            self._integral = min(max(self._integral + self.i * error * dt, -self.i_clamp), self.i_clamp)
        effort = self.p * error + self._integral + self.d * error_dot
        limit = self.effort_limit
        return -limit if effort < -limit else (limit if effort > limit else effort)


class World:
    """A PyBullet world holding one robot on a ground plane, stepped in fixed time steps."""

    def __init__(self, urdf_text: str, config: RobotConfig, time_step: float = 0.001, seed: int = 0,
                 gui: bool = False, urdf_source: str = "robot_description"):
        if not (time_step > 0.0 and math.isfinite(time_step)):
            raise ConfigError(f"time_step must be a positive number of seconds, got {time_step!r}")
        self.robot_name, urdf_joints = parse_urdf_joints(urdf_text, urdf_source)
        for controller in config.controllers:
            if controller.joint not in urdf_joints:
                raise ConfigError(f"controller {controller.name!r} names joint {controller.joint!r}, which "
                                  f"{urdf_source} does not have (joints: {', '.join(sorted(urdf_joints)) or 'none'})")
        self.config = config
        self.time_step = time_step
        self.seed = seed
        self.step_count = 0
        self._rng = np.random.default_rng(seed)
        self._cid = p.connect(p.GUI if gui else p.DIRECT)
        if self._cid < 0:
            raise RuntimeError("PyBullet could not connect" + (" to a GUI (is DISPLAY set?)" if gui else ""))
        if gui:
            p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, physicsClientId=self._cid)  # the 3D view alone
        try:
            self._build(urdf_text, urdf_joints, urdf_source)
        except Exception:
            p.disconnect(self._cid)
            raise

    # -- construction ---------------------------------------------------------------------------
    def _build(self, urdf_text: str, urdf_joints: Dict[str, UrdfJoint], urdf_source: str) -> None:
        cid = self._cid
        p.setPhysicsEngineParameter(fixedTimeStep=self.time_step, deterministicOverlappingPairs=1, physicsClientId=cid)
        p.setGravity(*GRAVITY, physicsClientId=cid)
        plane_shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        self._plane = p.createMultiBody(0, plane_shape, physicsClientId=cid)
        p.changeDynamics(self._plane, -1, lateralFriction=1.0, physicsClientId=cid)

        with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as handle:
            handle.write(urdf_text)
        try:
            self._body = p.loadURDF(handle.name, self.config.spawn_xyz, p.getQuaternionFromEuler(self.config.spawn_rpy),
                                    flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid)
        except p.error as error:
            raise UrdfError(f"{urdf_source} could not be loaded by PyBullet ({error}); check its links, joints "
                            f"and inertials") from None
        finally:
            os.unlink(handle.name)

        self._link_index = {p.getBodyInfo(self._body, physicsClientId=cid)[0].decode(): -1}
        movable: List[int] = []
        joint_index: Dict[str, int] = {}
        info = {}
        for index in range(p.getNumJoints(self._body, physicsClientId=cid)):
            ji = p.getJointInfo(self._body, index, physicsClientId=cid)
            name, jtype = ji[1].decode(), ji[2]
            self._link_index[ji[12].decode()] = index
            info[name] = ji
            joint_index[name] = index
            # Gazebo applies no velocity damping; PyBullet's defaults would brake a spinning wheel.
            p.changeDynamics(self._body, index, linearDamping=0.0, angularDamping=0.0,
                             maxJointVelocity=max(ji[11], 1.0) if ji[11] > 0 else 1000.0, physicsClientId=cid)
            if jtype in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
                movable.append(index)
        p.changeDynamics(self._body, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)
        self._movable = movable
        self.joint_names = tuple(p.getJointInfo(self._body, i, physicsClientId=cid)[1].decode() for i in movable)
        # Effort control needs PyBullet's default velocity motors switched off.
        p.setJointMotorControlArray(self._body, movable, p.VELOCITY_CONTROL, forces=[0.0] * len(movable),
                                    physicsClientId=cid)

        self._controllers: List[_EffortPid] = []
        for controller in self.config.controllers:
            ji = info[controller.joint]
            if ji[2] not in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
                raise ConfigError(f"controller {controller.name!r} names joint {controller.joint!r}, which is "
                                  f"{urdf_joints[controller.joint].type}, not movable")
            self._controllers.append(_EffortPid(controller, ji[0], effort_limit=ji[10], lower=ji[8], upper=ji[9],
                                                continuous=urdf_joints[controller.joint].type == "continuous"))
        self._controller_by_name = {c.config.name: c for c in self._controllers}
        self._controlled_indices = [c.joint_index for c in self._controllers]
        # joint_states' effort column: each movable joint's controller output of the last step, or 0
        self._effort_slots = [self._controlled_indices.index(i) if i in self._controlled_indices else None
                              for i in movable]
        self._controller_efforts = [0.0] * len(self._controllers)

        for sensor in self.config.sensors:
            if sensor.link not in self._link_index:
                raise ConfigError(f"sensor {sensor.name!r} names link {sensor.link!r}, which {urdf_source} does not "
                                  f"have (links: {', '.join(sorted(self._link_index))})")
        self._imu_previous: Dict[str, Tuple[float, Tuple[float, float, float]]] = {}
        self._saved_state = p.saveState(physicsClientId=cid)
        self._reset_controllers()

    # -- time and commands ----------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Simulated seconds since the start or the last reset_simulation."""
        return self.step_count * self.time_step

    def set_command(self, controller: str, value: float) -> bool:
        """Set a controller's command (rad/s or rad). A NaN or infinite value is ignored: returns False."""
        if not math.isfinite(value):
            return False
        self._controller_by_name[controller].command = float(value)
        return True

    def command(self, controller: str) -> float:
        return self._controller_by_name[controller].command

    def step(self, count: int = 1) -> None:
        """Advance `count` physics steps, running every controller before each one."""
        cid, body, dt = self._cid, self._body, self.time_step
        controllers, indices = self._controllers, self._controlled_indices
        efforts = self._controller_efforts
        for _ in range(count):
            if controllers:
                states = p.getJointStates(body, indices, physicsClientId=cid)
                efforts = [c.effort(s[0], s[1], dt) for c, s in zip(controllers, states)]
                p.setJointMotorControlArray(body, indices, p.TORQUE_CONTROL, forces=efforts, physicsClientId=cid)
            p.stepSimulation(physicsClientId=cid)
        self.step_count += count
        self._controller_efforts = efforts

    # -- resets ---------------------------------------------------------------------------------
    def _reset_controllers(self) -> None:
        states = p.getJointStates(self._body, self._controlled_indices, physicsClientId=self._cid) if self._controllers else []
        for controller, state in zip(self._controllers, states):
            controller.reset(state[0])
        self._controller_efforts = [0.0] * len(self._controllers)
        self._imu_previous.clear()

    def reset_world(self) -> None:
        """Back to the spawn pose at rest with controllers restarted; time keeps going."""
        p.restoreState(self._saved_state, physicsClientId=self._cid)
        # restoreState keeps the contact points of the last step: recompute them for the restored pose.
        p.performCollisionDetection(physicsClientId=self._cid)
        self._reset_controllers()

    def reset_simulation(self) -> None:
        """reset_world, plus time back to 0 and the noise generator restarted from the seed."""
        self.reset_world()
        self.step_count = 0
        self._rng = np.random.default_rng(self.seed)

    def close(self) -> None:
        if self._cid >= 0:
            p.disconnect(self._cid)
            self._cid = -1

    # -- sensors --------------------------------------------------------------------------------
    def _link_pose_twist(self, link: str):
        index, cid = self._link_index[link], self._cid
        if index == -1:
            position, orientation = p.getBasePositionAndOrientation(self._body, physicsClientId=cid)
            linear, angular = p.getBaseVelocity(self._body, physicsClientId=cid)
        else:
            state = p.getLinkState(self._body, index, computeLinkVelocity=1, computeForwardKinematics=1,
                                   physicsClientId=cid)
            position, orientation, linear, angular = state[4], state[5], state[6], state[7]
        return position, orientation, linear, angular

    def read_joint_states(self) -> JointStateReading:
        states = p.getJointStates(self._body, self._movable, physicsClientId=self._cid)
        efforts = self._controller_efforts
        return JointStateReading(stamp=self.time, name=self.joint_names,
                                 position=tuple(s[0] for s in states), velocity=tuple(s[1] for s in states),
                                 effort=tuple(0.0 if slot is None else efforts[slot] for slot in self._effort_slots))

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
        proper = [a - g for a, g in zip(acceleration, GRAVITY)]
        angular_body = _transpose_rotate(orientation, angular)
        proper_body = _transpose_rotate(orientation, proper)
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
        total_force = (0.0, 0.0, 0.0)
        total_torque = (0.0, 0.0, 0.0)
        for point in points:
            normal, normal_force = point[7], point[9]
            f1, d1, f2, d2 = point[10], point[11], point[12], point[13]
            force = tuple(normal_force * n + f1 * a + f2 * b for n, a, b in zip(normal, d1, d2))
            position = point[5]
            torque = _cross(tuple(c - o for c, o in zip(position, origin)), force)
            total_force = tuple(t + f for t, f in zip(total_force, force))
            total_torque = tuple(t + q for t, q in zip(total_torque, torque))
            other = GROUND_COLLISION_NAME if point[2] == self._plane else f"{self.robot_name}::link{point[4]}::collision"
            if in_link_frame:
                force, torque, normal = (_transpose_rotate(orientation, v) for v in (force, torque, normal))
            contacts.append(ContactPoint(collision1_name=own_name, collision2_name=other, force=force,
                                         torque=torque, position=tuple(position), normal=tuple(normal),
                                         depth=-point[8]))
        if in_link_frame:
            total_force = _transpose_rotate(orientation, total_force)
            total_torque = _transpose_rotate(orientation, total_torque)
        return ContactReading(stamp=self.time, frame_id=sensor.frame_id, contacts=tuple(contacts),
                              total_force=total_force, total_torque=total_torque)

    def read_sensor(self, sensor: SensorConfig):
        """The reading of one configured sensor (odometry, IMU or contact)."""
        return _READERS[sensor.type](self, sensor)

    # -- rendering ------------------------------------------------------------------------------
    def _camera_target(self) -> tuple[float, float, float]:
        x, y, z = p.getBasePositionAndOrientation(self._body, physicsClientId=self._cid)[0]
        return (x, y, z + self.config.camera.z_offset)

    def render(self, width: int, height: int) -> np.ndarray:
        """An RGB image (height x width x 3, uint8) from the camera that follows the robot's base
        (config.camera), drawn by PyBullet's TinyRenderer, which needs no display. Changes nothing."""
        if not all(isinstance(v, int) and 1 <= v <= MAX_IMAGE_SIZE for v in (width, height)):
            raise ValueError(f"image size must be whole pixels from 1 to {MAX_IMAGE_SIZE} a side, got {width!r} x "
                             f"{height!r}")
        camera, cid = self.config.camera, self._cid
        view = p.computeViewMatrixFromYawPitchRoll(self._camera_target(), camera.distance, camera.yaw, camera.pitch,
                                                   0.0, 2, physicsClientId=cid)
        projection = p.computeProjectionMatrixFOV(camera.fov, width / height, 0.01, 100.0, physicsClientId=cid)
        rgba = p.getCameraImage(width, height, view, projection, renderer=p.ER_TINY_RENDERER, physicsClientId=cid)[2]
        return np.ascontiguousarray(np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3])

    def aim_gui_camera(self) -> None:
        """Point the GUI window's camera (World(gui=True)) at the robot as render() does."""
        camera = self.config.camera
        p.resetDebugVisualizerCamera(camera.distance, camera.yaw, camera.pitch, self._camera_target(),
                                     physicsClientId=self._cid)

    def link_pose(self, link: str):
        """Noise-free world pose of a link's URDF frame."""
        position, orientation, _, _ = self._link_pose_twist(link)
        return tuple(position), tuple(orientation)


_READERS = {"p3d": World.read_odometry, "imu": World.read_imu, "contact": World.read_contact}
