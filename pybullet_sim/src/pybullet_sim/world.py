"""The physics world that stands in for Gazebo: PyBullet plus ros_control-style controllers and sensors.

No ROS here: a World loads a URDF and a RobotConfig, advances time in fixed physics steps, and hands
out plain readings (pybullet_sim.readings). The sim node wraps it for ROS; task envs can also drive
it in-process (the "direct" backend) with the same results.

Semantics kept from Gazebo + ros_control:
- effort_controllers/JointVelocityController and JointPositionController are effort PIDs evaluated
  every physics step. Commands are clamped to the URDF limits (a velocity command to the velocity
  limit, a position command to the position limits) and the effort to the effort limit, as ros_control's
  joint limits interface does.
- Controllers can be stopped and started (ros_control's switch_controller): a stopped controller applies
  no effort and ignores commands; starting one restarts it (a position controller holds the current
  position, a velocity controller stops). Resets restart the running ones and leave stopped ones stopped.
- p3d odometry adds seeded Gaussian noise to position, orientation (as roll/pitch/yaw), and both
  velocities; pose and twist are in the world frame.
- The IMU reports world orientation, body-frame angular velocity and body-frame proper acceleration.
- The contact sensor reports the touching pairs of one link; no contacts means an empty list.
- reset_world restores poses, velocities and controllers; reset_simulation also sets time back to 0
  and restarts the noise generator from the seed. Gravity, the time step and the solver settings
  (Gazebo's physics properties) are kept across both, as in Gazebo.
- Model and link states are the pose and twist of URDF link frames in the world frame.

Replayed starts: every reset restores one saved state, and PyBullet is deterministic, so the first
physics steps after a reset end in the same state whenever they are taken with the same commands (the
cube's 0.15 s landing after each reset is the case that costs: about 2.5 env steps). replay_from_reset
restores that end state once it has seen the same start twice (PyBullet's saveState takes about 0.8 ms,
some 45 of the cube's physics steps; restoreState a few microseconds); the trajectory that follows is bit
for bit the one the steps would have given (test_world.py checks this for both robots). A World with
PyBullet's window never replays: there the mouse can move the robot during the steps.
"""
from __future__ import annotations

import math
import os
import tempfile
import xml.etree.ElementTree as ElementTree
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pybullet as p

from .config import ConfigError, JointControllerConfig, RobotConfig, SensorConfig
from .readings import ContactPoint, ContactReading, FrameState, ImuReading, JointStateReading, OdometryReading

DEFAULT_GRAVITY = (0.0, 0.0, -9.81)
MAX_IMAGE_SIZE = 4096  # pixels per side of a rendered image
GROUND_COLLISION_NAME = "ground_plane::link::collision"
MIN_TIME_STEP = 1e-6  # s; sim time counts whole nanoseconds

# Why the moving cube was thrown kilometres from a wheel speed of about 400 rad/s (issue 14), and what
# keeps it physical up to the URDF's 1000 rad/s:
# Bullet's Featherstone multibody adds the velocity-product terms (each link's gyroscopic torque w x Iw
# and the Coriolis terms) explicitly, once per step: a body spinning at w turns w * h rad in a step h,
# and the error grows with w^2 * h. Measured on the cube at h = 1 ms (World of commit a103b49, wheel
# commanded at one speed for 5 s, mechanical energy against the motor's work): at 100 and 300 rad/s the
# energy never exceeds the work; at 600 rad/s it exceeds it by 3.9e4 J (work 276 J) and the cube ends
# 837 m away, at 1000 rad/s by 2.8e5 J and 2212 m. Floating without gravity or contact, where the centre
# of mass must not move, it drifts 0.19 m in 2 s at 600 rad/s and 168 m at 1000 rad/s. Not the cause:
# contact stiffness and damping (PyBullet's default contact: the same figures), solver iterations (50 or
# 200: the same), the wheel's maxJointVelocity (2000 instead of 1000: still thrown). What decides is
# w^2 * h: no energy gained up to 90 rad^2/s (300 rad/s at 1 ms, 600 at 1/4 ms, 1000 at 1/16 ms), energy
# gained from 125 rad^2/s up (400 rad/s at 1 ms, 1000 at 1/8 ms). So a step whose fastest link spins
# faster than SPIN_STEP_LIMIT allows is split into 2, 4, ... equal PyBullet substeps, efforts held (as
# ros_control holds a command for a control period). At ordinary speeds (the cube's training commands
# reach 100 rad/s: 10 rad^2/s) a step stays one PyBullet step and trajectories are unchanged; at
# 1000 rad/s it takes 32 substeps, the energy stays below the motor's work for 10 s and the floating
# cube's centre of mass moves less than 1 mm.
# Gazebo is exposed to the same error at 1 ms: its ODE (gazebo-classic deps/opende/src/quickstep.cpp,
# dxQuickStepper) also adds every body's gyroscopic torque w x Iw explicitly (dxBodyGyroscopic is set on
# every body). Gazebo drone models (RotorS) spin their rotor joints 10 times slower than the real rotors
# and warn of aliasing when a rotor turns too far in one step.
SPIN_STEP_LIMIT = 40.0  # rad^2/s: the largest w^2 * h of one PyBullet step, half of the measured safe bound
MAX_SUBSTEPS = 64
MAX_REMEMBERED_STARTS = 8  # end states of starts after a reset a World keeps (see replay_from_reset)
MAX_SEEN_STARTS = 256      # starts a World counts while it waits to see one a second time


@dataclass(frozen=True)
class SolverSettings:
    """The settings of PyBullet's constraint solver that Gazebo's ODE settings map onto (PyBullet's defaults)."""

    iterations: int = 50  # numSolverIterations (ODE sor_pgs_iters)
    residual_threshold: float = 1e-7  # solverResidualThreshold: stop iterating below it (ODE sor_pgs_rms_error_tol)
    erp: float = 0.2  # error reduction of joint limits and motors (ODE erp; contacts use the URDF's stiffness)
    cfm: float = 0.0  # globalCFM, constraint force mixing of every constraint (ODE cfm)


class UrdfError(ValueError):
    """The robot description is missing, not XML, or not a URDF PyBullet can load."""


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    type: str


def parse_urdf_joints(urdf_text: str, source: str) -> tuple[str, dict[str, UrdfJoint]]:
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
    joints = {}
    for element in root.findall("joint"):
        name, kind = element.get("name"), element.get("type")
        if not name or not kind:
            raise UrdfError(f"{source} is not a URDF: a <joint> has no name or no type")
        joints[name] = UrdfJoint(name, kind)
    return str(root.get("name")), joints


def _transpose_rotate(quaternion: Sequence[float], vector: Sequence[float]) -> tuple[float, float, float]:
    """Express a world-frame vector in the frame whose world orientation is `quaternion`."""
    m = p.getMatrixFromQuaternion(quaternion)
    x, y, z = vector
    return (m[0] * x + m[3] * y + m[6] * z, m[1] * x + m[4] * y + m[7] * z, m[2] * x + m[5] * y + m[8] * z)


def _cross(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _quaternion_multiply(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float, float]:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def _rotate(quaternion: Sequence[float], vector: Sequence[float]) -> tuple[float, float, float]:
    """A vector turned by a unit quaternion (x, y, z, w), in double precision (PyBullet's transforms are float)."""
    axis, w = quaternion[:3], quaternion[3]
    t = tuple(2.0 * c for c in _cross(axis, vector))
    turned = _cross(axis, t)
    return (vector[0] + w * t[0] + turned[0], vector[1] + w * t[1] + turned[1], vector[2] + w * t[2] + turned[2])


def relative_state(state: FrameState, frame: FrameState) -> FrameState:
    """A world-frame state expressed in another frame, as gazebo_ros's get_model_state and get_link_state do:
    the pose relative to the frame, the velocity differences turned into the frame's axes."""
    x, y, z, w = frame.orientation
    inverse = (-x, -y, -z, w)
    position = _rotate(inverse, [a - b for a, b in zip(state.position, frame.position, strict=True)])
    linear = _rotate(inverse, [a - b for a, b in zip(state.linear_velocity, frame.linear_velocity, strict=True)])
    angular = _rotate(inverse, [a - b for a, b in zip(state.angular_velocity, frame.angular_velocity, strict=True)])
    return FrameState(position, _quaternion_multiply(inverse, state.orientation), linear, angular)


def absolute_state(state: FrameState, frame: FrameState) -> FrameState:
    """A state given in another frame, in the world frame, as gazebo_ros's set_model_state takes it: the pose
    composed with the frame's, the velocities turned into world axes (the frame's own velocity is not added)."""
    turned = [_rotate(frame.orientation, v) for v in (state.position, state.linear_velocity, state.angular_velocity)]
    position = tuple(a + b for a, b in zip(turned[0], frame.position, strict=True))
    return FrameState(position, _quaternion_multiply(frame.orientation, _normalized(state.orientation)),
                      turned[1], turned[2])


def _normalized(quaternion: Sequence[float]) -> tuple[float, ...]:
    """A unit quaternion; all zeros (a default geometry_msgs/Pose) means no rotation, as in Gazebo."""
    norm = math.sqrt(sum(q * q for q in quaternion))
    return (0.0, 0.0, 0.0, 1.0) if norm < 1e-12 else tuple(q / norm for q in quaternion)


def _check_time_step(time_step: float, error: type) -> None:
    if not (isinstance(time_step, (int, float)) and math.isfinite(time_step) and time_step >= MIN_TIME_STEP):
        raise error(f"time_step must be a finite number of seconds >= {MIN_TIME_STEP:g}, got {time_step!r}")


class _EffortPid:
    """One ros_control effort PID (control_toolbox::Pid) on one joint."""

    def __init__(self, config: JointControllerConfig, joint_index: int, effort_limit: float, velocity_limit: float,
                 lower: float, upper: float, continuous: bool):
        self.config = config
        self.joint_index = joint_index
        self.effort_limit = effort_limit
        self.velocity_limit = velocity_limit  # 0 when the URDF gives none
        self.running = True
        self.lower, self.upper = lower, upper
        self.has_limits = not continuous and lower < upper
        self.continuous = continuous
        self.is_position = config.is_position
        gains = config.pid
        self.p, self.i, self.d, self.i_clamp = gains.p, gains.i, gains.d, gains.i_clamp
        self.command = 0.0
        self._integral = 0.0
        self._previous_error = 0.0

    @property
    def memory(self) -> tuple[float, float]:
        """What the PID carries from one step to the next besides its command: (integral, previous error)."""
        return self._integral, self._previous_error

    @memory.setter
    def memory(self, value: tuple[float, float]) -> None:
        self._integral, self._previous_error = value

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
            limit = self.velocity_limit
            target = min(max(self.command, -limit), limit) if limit > 0.0 else self.command
            error = target - velocity
            error_dot = (error - self._previous_error) / dt
            self._previous_error = error
        if self.i_clamp > 0.0:
            self._integral = min(max(self._integral + self.i * error * dt, -self.i_clamp), self.i_clamp)
        effort = self.p * error + self._integral + self.d * error_dot
        limit = self.effort_limit
        return -limit if effort < -limit else (limit if effort > limit else effort)


@dataclass(frozen=True)
class _StartKey:
    """The first steps after a reset: how many, and every controller's command, running state and memory."""

    steps: int
    controllers: tuple[tuple[float, bool, tuple[float, float]], ...]


@dataclass(frozen=True)
class _StartEnd:
    """Where those steps end: PyBullet's saved state and what the World keeps beside it."""

    state: int                                   # a PyBullet saveState id
    controller_memories: tuple[tuple[float, float], ...]
    efforts: tuple[float, ...]
    substeps: int


class World:
    """A PyBullet world holding one robot on a ground plane, stepped in fixed time steps."""

    def __init__(self, urdf_text: str, config: RobotConfig, time_step: float = 0.001, seed: int = 0,
                 gui: bool = False, urdf_source: str = "robot_description"):
        _check_time_step(time_step, ConfigError)
        self.robot_name, urdf_joints = parse_urdf_joints(urdf_text, urdf_source)
        for controller in config.controllers:
            if controller.joint not in urdf_joints:
                raise ConfigError(f"controller {controller.name!r} names joint {controller.joint!r}, which "
                                  f"{urdf_source} does not have (joints: {', '.join(sorted(urdf_joints)) or 'none'})")
        self.config = config
        self.time_step = time_step
        self.seed = seed
        self.step_count = 0  # physics steps since the start or the last reset_simulation
        self._time_ns = 0
        self._step_ns = round(time_step * 1e9)
        self._substeps = 1
        self._gravity = DEFAULT_GRAVITY
        self._solver = SolverSettings()
        self._rng = np.random.default_rng(seed)
        self._at_reset = False  # nothing but commands has changed since the last reset (see replay_from_reset)
        self._replays = not gui  # in PyBullet's window a user can drag the robot during the steps: never replay
        self._start_ends: dict[_StartKey, _StartEnd] = {}
        self._starts_seen: set[_StartKey] = set()
        self._recording: tuple[_StartKey, int] | None = None  # a start to remember when step_count reaches this
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
    def _build(self, urdf_text: str, urdf_joints: dict[str, UrdfJoint], urdf_source: str) -> None:
        cid = self._cid
        p.setPhysicsEngineParameter(fixedTimeStep=self.time_step, deterministicOverlappingPairs=1, physicsClientId=cid)
        p.setGravity(*self._gravity, physicsClientId=cid)
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
        info = {}
        for index in range(p.getNumJoints(self._body, physicsClientId=cid)):
            ji = p.getJointInfo(self._body, index, physicsClientId=cid)
            self._link_index[ji[12].decode()] = index
            info[ji[1].decode()] = ji
        # Bullet clamps every velocity coordinate of a multibody, the base's included, to one maxJointVelocity,
        # whichever link it is set on. It gets one value, at or above every URDF velocity limit, so that it
        # only catches runaway numbers: the limits themselves act through the controllers, as in ros_control.
        max_velocity = max([1000.0, *(ji[11] for ji in info.values())])
        for index in (-1, *range(len(info))):
            # Gazebo applies no velocity damping; PyBullet's defaults would brake a spinning wheel.
            p.changeDynamics(self._body, index, linearDamping=0.0, angularDamping=0.0, maxJointVelocity=max_velocity,
                             physicsClientId=cid)
        movable_info = [ji for ji in info.values() if ji[2] in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC)]
        self._movable = movable = [ji[0] for ji in movable_info]
        self._revolute_slots = [slot for slot, ji in enumerate(movable_info) if ji[2] == p.JOINT_REVOLUTE]
        self.joint_names = tuple(ji[1].decode() for ji in movable_info)
        # Effort control needs PyBullet's default velocity motors switched off.
        p.setJointMotorControlArray(self._body, movable, p.VELOCITY_CONTROL, forces=[0.0] * len(movable),
                                    physicsClientId=cid)

        self._controllers: list[_EffortPid] = []
        for controller in self.config.controllers:
            ji = info[controller.joint]
            if ji[2] not in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
                raise ConfigError(f"controller {controller.name!r} names joint {controller.joint!r}, which is "
                                  f"{urdf_joints[controller.joint].type}, not movable")
            self._controllers.append(_EffortPid(controller, ji[0], effort_limit=ji[10], velocity_limit=ji[11],
                                                lower=ji[8], upper=ji[9],
                                                continuous=urdf_joints[controller.joint].type == "continuous"))
        self._controller_by_name = {c.config.name: c for c in self._controllers}
        self._controlled_indices = [c.joint_index for c in self._controllers]
        self._controller_slots = [movable.index(i) for i in self._controlled_indices]
        # joint_states' effort column: each movable joint's controller output of the last step, or 0
        self._effort_slots = [self._controlled_indices.index(i) if i in self._controlled_indices else None
                              for i in movable]
        self._controller_efforts = [0.0] * len(self._controllers)

        for sensor in self.config.sensors:
            if sensor.link not in self._link_index:
                raise ConfigError(f"sensor {sensor.name!r} names link {sensor.link!r}, which {urdf_source} does not "
                                  f"have (links: {', '.join(sorted(self._link_index))})")
        self._imu_previous: dict[str, tuple[float, tuple[float, float, float]]] = {}
        self._saved_state = p.saveState(physicsClientId=cid)
        self._reset_controllers()

    # -- time and commands ----------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Simulated seconds since the start or the last reset_simulation."""
        return self._time_ns / 1e9

    @property
    def time_ns(self) -> int:
        """Simulated nanoseconds since the start or the last reset_simulation (each step adds the time step)."""
        return self._time_ns

    def set_command(self, controller: str, value: float) -> bool:
        """Set a controller's command (rad/s or rad). A NaN or infinite value is ignored: returns False.

        A stopped controller ignores commands (its start sets the command)."""
        if not math.isfinite(value):
            return False
        pid = self._controller_by_name[controller]
        if pid.running:
            pid.command = float(value)
            self._recording = None
        return True

    def command(self, controller: str) -> float:
        return self._controller_by_name[controller].command

    def step(self, count: int = 1) -> None:
        """Advance `count` physics steps, running every controller before each one."""
        self._at_reset = False
        cid, body, dt = self._cid, self._body, self.time_step
        controllers, slots, indices = self._controllers, self._controller_slots, self._controlled_indices
        efforts = self._controller_efforts
        for _ in range(count):
            states = p.getJointStates(body, self._movable, physicsClientId=cid)
            efforts = [c.effort(states[s][0], states[s][1], dt) if c.running else 0.0
                       for c, s in zip(controllers, slots, strict=True)]
            for _ in range(self._substeps_for(states)):
                if controllers:  # PyBullet applies a joint torque for one stepSimulation only
                    p.setJointMotorControlArray(body, indices, p.TORQUE_CONTROL, forces=efforts, physicsClientId=cid)
                p.stepSimulation(physicsClientId=cid)
        self._advance_time(count)
        self._controller_efforts = efforts
        if self._recording is not None and self.step_count >= self._recording[1]:
            if self.step_count == self._recording[1]:
                self._remember_start(self._recording[0])
            self._recording = None

    def replay_from_reset(self, count: int) -> bool:
        """Take the first `count` physics steps after a reset, with the commands set since, from memory.

        True when the World has restored where these steps ended before (time advances by `count`);
        False when the caller must take them with step(), in one call or several. A start is remembered
        the second time it is seen (up to MAX_REMEMBERED_STARTS of them), and only when nothing but
        commands changed between the reset and these steps, and nothing at all during them; never in a
        World with PyBullet's window, where the mouse can move the robot."""
        if not (self._at_reset and self._replays):
            return False
        self._at_reset = False
        key = _StartKey(count, tuple((c.command, c.running, c.memory) for c in self._controllers))
        end = self._start_ends.get(key)
        if end is None:
            if key in self._starts_seen and len(self._start_ends) < MAX_REMEMBERED_STARTS:
                self._recording = (key, self.step_count + count)
            elif len(self._starts_seen) >= MAX_SEEN_STARTS:
                self._starts_seen.clear()
            self._starts_seen.add(key)
            return False
        p.restoreState(end.state, physicsClientId=self._cid)
        for controller, memory in zip(self._controllers, end.controller_memories, strict=True):
            controller.memory = memory
        self._controller_efforts = list(end.efforts)
        if end.substeps != self._substeps:
            self._set_substeps(end.substeps)
        self._advance_time(count)
        return True

    def _advance_time(self, count: int) -> None:
        self.step_count += count
        self._time_ns += count * self._step_ns

    def _remember_start(self, key: _StartKey) -> None:
        self._start_ends[key] = _StartEnd(p.saveState(physicsClientId=self._cid),
                                          tuple(c.memory for c in self._controllers),
                                          tuple(self._controller_efforts), self._substeps)

    def _forget_starts(self) -> None:
        """The physics changed (gravity, time step, solver): no remembered start holds any more."""
        for end in self._start_ends.values():
            p.removeState(end.state, physicsClientId=self._cid)
        self._start_ends.clear()
        self._starts_seen.clear()
        self._at_reset = False
        self._recording = None

    @property
    def substeps(self) -> int:
        """How many PyBullet steps the last physics step took (1 unless a link spun fast; see SPIN_STEP_LIMIT)."""
        return self._substeps

    def _substeps_for(self, joint_states) -> int:
        """How many PyBullet substeps the next step needs (see SPIN_STEP_LIMIT); sets PyBullet's step to match."""
        spin = math.sqrt(sum(w * w for w in p.getBaseVelocity(self._body, physicsClientId=self._cid)[1]))
        spin += sum(abs(joint_states[slot][1]) for slot in self._revolute_slots)  # bounds every link's |w|
        load = spin * spin * self.time_step
        substeps = 1
        while load > SPIN_STEP_LIMIT * substeps and substeps < MAX_SUBSTEPS:
            substeps *= 2
        if substeps != self._substeps:
            self._set_substeps(substeps)
        return substeps

    def _set_substeps(self, substeps: int) -> None:
        """Make each PyBullet step 1/substeps of the physics step."""
        p.setPhysicsEngineParameter(fixedTimeStep=self.time_step / substeps, physicsClientId=self._cid)
        self._substeps = substeps

    # -- controllers (ros_control's controller manager drives these) ----------------------------
    @property
    def controller_names(self) -> tuple[str, ...]:
        return tuple(c.config.name for c in self._controllers)

    def controller_running(self, controller: str) -> bool:
        return self._controller_by_name[controller].running

    def start_controller(self, controller: str) -> None:
        """(Re)start a controller: a position controller holds the current position, a velocity one stops."""
        pid = self._controller_by_name[controller]
        pid.reset(p.getJointState(self._body, pid.joint_index, physicsClientId=self._cid)[0])
        pid.running = True
        self._recording = None

    def stop_controller(self, controller: str) -> None:
        """Stop a controller: from the next step on it applies no effort and ignores commands."""
        self._controller_by_name[controller].running = False
        self._recording = None

    # -- physics properties (Gazebo's set_physics_properties) -----------------------------------
    @property
    def gravity(self) -> tuple[float, float, float]:
        return self._gravity

    def set_gravity(self, gravity: Sequence[float]) -> None:
        """Set the gravity vector (m/s^2, world frame) from the next step on; resets keep it."""
        values = tuple(float(g) for g in gravity)
        if len(values) != 3 or not all(math.isfinite(g) for g in values):
            raise ValueError(f"gravity must be three finite numbers, got {tuple(gravity)!r}")
        p.setGravity(*values, physicsClientId=self._cid)
        self._gravity = values
        self._forget_starts()

    def set_time_step(self, time_step: float) -> None:
        """Change the physics step (s) from the next step on; sim time stays continuous."""
        _check_time_step(time_step, ValueError)
        self.time_step = float(time_step)
        self._step_ns = round(self.time_step * 1e9)
        self._substeps = 1
        p.setPhysicsEngineParameter(fixedTimeStep=self.time_step, physicsClientId=self._cid)
        self._forget_starts()

    @property
    def solver(self) -> SolverSettings:
        return self._solver

    def set_solver(self, solver: SolverSettings) -> None:
        """Apply constraint solver settings (see SolverSettings); resets keep them."""
        if not (isinstance(solver.iterations, int) and solver.iterations >= 1):
            raise ValueError(f"solver iterations must be an integer >= 1, got {solver.iterations!r}")
        for name in ("residual_threshold", "erp", "cfm"):
            value = getattr(solver, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"solver {name} must be a finite number >= 0, got {value!r}")
        if solver.erp > 1.0:
            raise ValueError(f"solver erp must be at most 1, got {solver.erp!r}")
        p.setPhysicsEngineParameter(numSolverIterations=solver.iterations,
                                    solverResidualThreshold=solver.residual_threshold, erp=solver.erp,
                                    globalCFM=solver.cfm, physicsClientId=self._cid)
        self._solver = solver
        self._forget_starts()

    # -- model and link states (Gazebo's get/set_model_state, get_link_state) -------------------
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
            orientation = _quaternion_multiply(com_orientation, (-x, -y, -z, w))
            position = tuple(c - o for c, o in zip(com, _rotate(orientation, inertial_position), strict=True))
        else:
            state = p.getLinkState(body, index, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=cid)
            com, position, orientation, com_velocity, angular = state[0], state[4], state[5], state[6], state[7]
        offset = tuple(a - b for a, b in zip(position, com, strict=True))
        linear = tuple(v + w for v, w in zip(com_velocity, _cross(angular, offset), strict=True))
        return FrameState(tuple(position), tuple(orientation), linear, tuple(angular))

    def set_model_state(self, state: FrameState) -> None:
        """Move the robot's base frame to a pose with a twist (world frame); the joints keep their state.

        As Gazebo does, the orientation is normalised and an all-zero quaternion means no rotation.
        ValueError if any number is not finite."""
        numbers = (*state.position, *state.orientation, *state.linear_velocity, *state.angular_velocity)
        if len(numbers) != 13 or not all(math.isfinite(v) for v in numbers):
            raise ValueError(f"the pose and twist must be finite numbers, got {state!r}")
        orientation = _normalized(state.orientation)
        inertial_position, inertial_orientation = p.getDynamicsInfo(self._body, -1, physicsClientId=self._cid)[3:5]
        com = tuple(a + b for a, b in zip(state.position, _rotate(orientation, inertial_position), strict=True))
        com_orientation = _quaternion_multiply(orientation, inertial_orientation)
        offset = tuple(a - b for a, b in zip(com, state.position, strict=True))
        spin = _cross(state.angular_velocity, offset)
        com_velocity = tuple(v + w for v, w in zip(state.linear_velocity, spin, strict=True))
        p.resetBasePositionAndOrientation(self._body, com, com_orientation, physicsClientId=self._cid)
        p.resetBaseVelocity(self._body, com_velocity, state.angular_velocity, physicsClientId=self._cid)
        p.performCollisionDetection(physicsClientId=self._cid)
        self._imu_previous.clear()
        self._at_reset = False
        self._recording = None

    # -- resets ---------------------------------------------------------------------------------
    def _reset_controllers(self) -> None:
        """Restart every controller as gazebo_ros_control does on a reset; stopped ones stay stopped."""
        states = (p.getJointStates(self._body, self._controlled_indices, physicsClientId=self._cid)
                  if self._controllers else [])
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
        self._at_reset = True
        self._recording = None

    def reset_simulation(self) -> None:
        """reset_world, plus time back to 0 and the noise generator restarted from the seed."""
        self.reset_world()
        self.step_count = 0
        self._time_ns = 0
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
        proper = [a - g for a, g in zip(acceleration, self._gravity, strict=True)]
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
        total_force: tuple[float, ...] = (0.0, 0.0, 0.0)
        total_torque: tuple[float, ...] = (0.0, 0.0, 0.0)
        for point in points:
            normal, normal_force = point[7], point[9]
            f1, d1, f2, d2 = point[10], point[11], point[12], point[13]
            force = tuple(normal_force * n + f1 * a + f2 * b for n, a, b in zip(normal, d1, d2))
            position = point[5]
            torque = _cross(tuple(c - o for c, o in zip(position, origin)), force)
            total_force = tuple(t + f for t, f in zip(total_force, force))
            total_torque = tuple(t + q for t, q in zip(total_torque, torque))
            other = (GROUND_COLLISION_NAME if point[2] == self._plane
                     else f"{self.robot_name}::link{point[4]}::collision")
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
