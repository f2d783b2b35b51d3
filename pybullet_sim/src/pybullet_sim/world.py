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
- The sim config's `base_constraint: vertical` (not Gazebo's) holds the base on a vertical slider: it keeps
  its spawn x, y and orientation and moves along world z only (set_model_state's pose is pulled back to it).
- The attitude assist (not Gazebo's; set_attitude_assist, a training curriculum's help) pulls the base upright:
  before every physics step a torque of stiffness x the sine of the base's tilt about the tilt's horizontal axis,
  minus damping x the base's horizontal angular velocity (world frame). Off (0, 0) by default; resets keep it.

Its sensor readers and model and link states are in pybullet_sim.measurements; replay_from_reset
takes the first steps after a reset from memory (pybullet_sim.starts), bit for bit as stepping would.
"""
from __future__ import annotations

import functools
import math
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar, cast

import numpy as np
import pybullet as p

from .config import RobotConfig, SensorConfig
from .errors import ConfigError, UrdfError
from .measurements import Measurements
from .pid import EffortPid
from .readings import FrameState, JointStateReading
from .scene import Scene, camera_target, check_image_size
from .sensors import SENSOR_KINDS
from .starts import MAX_REMEMBERED_STARTS, Change, StartKey, StartMemory
from .transforms import cross, normalized, quaternion_multiply, rotate, transpose_rotate
from .urdf import UrdfJoint, parse_urdf_joints
from .validation import frame_state_problem

__all__ = ["DEFAULT_GRAVITY", "MAX_ASSIST_GAIN", "MAX_REMEMBERED_STARTS", "SolverSettings", "World"]

DEFAULT_GRAVITY = (0.0, 0.0, -9.81)
MIN_TIME_STEP = 1e-6  # s; sim time counts whole nanoseconds
MAX_ASSIST_GAIN = 1e4  # N m/rad and N m s/rad: the attitude assist's bound (the monoped topples at ~6 N m/rad)

# Bullet adds the velocity-product terms (gyroscopic torque w x Iw, Coriolis) explicitly once per step, so a
# fast-spinning link gains energy: the error grows with w^2 * h (h: the PyBullet step). No energy is gained up to
# 90 rad^2/s and it is from 125 rad^2/s up (the cube's wheel, measured; test_fast_wheel.py checks the bound), so a
# step whose fastest link would pass SPIN_STEP_LIMIT is split into 2, 4, ... PyBullet substeps, efforts held as
# ros_control holds a command for a control period. Ordinary speeds keep one PyBullet step per physics step.
SPIN_STEP_LIMIT = 40.0  # rad^2/s: the largest w^2 * h of one PyBullet step, half of the measured safe bound
MAX_SUBSTEPS = 64
F = TypeVar("F", bound=Callable[..., Any])


@dataclass(frozen=True)
class SolverSettings:
    """The settings of PyBullet's constraint solver that Gazebo's ODE settings map onto (PyBullet's defaults)."""

    iterations: int = 50  # numSolverIterations (ODE sor_pgs_iters)
    residual_threshold: float = 1e-7  # solverResidualThreshold: stop iterating below it (ODE sor_pgs_rms_error_tol)
    erp: float = 0.2  # error reduction of joint limits and motors (ODE erp; contacts use the URDF's stiffness)
    cfm: float = 0.0  # globalCFM, constraint force mixing of every constraint (ODE cfm)


def _check_time_step(time_step: float, error: type) -> None:
    if not (isinstance(time_step, (int, float)) and math.isfinite(time_step) and time_step >= MIN_TIME_STEP):
        raise error(f"time_step must be a finite number of seconds >= {MIN_TIME_STEP:g}, got {time_step!r}")


@dataclass(frozen=True)
class _StartEnd:
    """Where the first steps after a reset ended: PyBullet's saved state and what the World keeps beside it."""

    state: int                                   # a PyBullet saveState id
    controller_memories: tuple[tuple[float, float], ...]
    efforts: tuple[float, ...]
    substeps: int


def _changes(kind: Change) -> Callable[[F], F]:
    """Mark a World method as one that changes the World: after it runs, the World's StartMemory is told
    `kind` (the only way it learns of changes; test_world.py checks every public method is marked or reads)."""
    def mark(method: F) -> F:
        @functools.wraps(method)
        def changing(self: World, *args: Any, **kwargs: Any) -> Any:
            result = method(self, *args, **kwargs)
            self._starts.changed(kind, self.step_count)
            return result
        changing.change = kind  # type: ignore[attr-defined]
        return cast(F, changing)
    return mark


class World(Measurements):
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
        self._urdf_text = urdf_text
        self._scene: Scene | None = None  # made by the first render()
        self.time_step = time_step
        self.seed = seed
        self.step_count = 0  # physics steps since the start or the last reset_simulation
        self._time_ns = 0
        self._step_ns = round(time_step * 1e9)
        self._substeps = 1
        self._gravity = DEFAULT_GRAVITY
        self._solver = SolverSettings()
        self._assist = (0.0, 0.0)  # the attitude assist's stiffness (N m/rad) and damping (N m s/rad)
        self._rng = np.random.default_rng(seed)
        # In PyBullet's window a user can drag the robot during the steps: never replay there.
        self._starts: StartMemory[_StartEnd] = StartMemory(self._save_start_end, self._discard_start_end,
                                                           enabled=not gui)
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

        if self.config.base_constraint == "vertical":  # the base slides along world z through its spawn pose
            com, orientation = p.getBasePositionAndOrientation(self._body, physicsClientId=cid)
            up = transpose_rotate(orientation, (0.0, 0.0, 1.0))  # world z in the base frame
            p.createConstraint(self._body, -1, -1, -1, p.JOINT_PRISMATIC, up, (0.0, 0.0, 0.0), com,
                               childFrameOrientation=orientation, physicsClientId=cid)

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

        self._controllers: list[EffortPid] = []
        for controller in self.config.controllers:
            ji = info[controller.joint]
            if ji[2] not in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
                raise ConfigError(f"controller {controller.name!r} names joint {controller.joint!r}, which is "
                                  f"{urdf_joints[controller.joint].type}, not movable")
            self._controllers.append(EffortPid(controller, ji[0], effort_limit=ji[10], velocity_limit=ji[11],
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
    def time_ns(self) -> int:
        """Simulated nanoseconds since the start or the last reset_simulation (each step adds the time step)."""
        return self._time_ns

    @_changes(Change.COMMANDS)
    def set_command(self, controller: str, value: float) -> bool:
        """Set a controller's command (rad/s or rad). A NaN or infinite value is ignored: returns False.

        A stopped controller ignores commands (its start sets the command)."""
        if not math.isfinite(value):
            return False
        pid = self._controller_by_name[controller]
        if pid.running:
            pid.command = float(value)
        return True

    def command(self, controller: str) -> float:
        return self._controller_by_name[controller].command

    @_changes(Change.STEPS)
    def step(self, count: int = 1) -> None:
        """Advance `count` physics steps, running every controller before each one."""
        cid, body, dt = self._cid, self._body, self.time_step
        controllers, slots, indices = self._controllers, self._controller_slots, self._controlled_indices
        efforts = self._controller_efforts
        for _ in range(count):
            states = p.getJointStates(body, self._movable, physicsClientId=cid)
            efforts = [c.effort(states[s][0], states[s][1], dt) if c.running else 0.0
                       for c, s in zip(controllers, slots, strict=True)]
            assist = self._assist_torque() if self._assist != (0.0, 0.0) else None
            for _ in range(self._substeps_for(states)):
                if controllers:  # PyBullet applies a joint torque for one stepSimulation only
                    p.setJointMotorControlArray(body, indices, p.TORQUE_CONTROL, forces=efforts, physicsClientId=cid)
                if assist is not None:  # an external torque too
                    p.applyExternalTorque(body, -1, assist, p.WORLD_FRAME, physicsClientId=cid)
                p.stepSimulation(physicsClientId=cid)
        self._advance_time(count)
        self._controller_efforts = efforts

    def replay_from_reset(self, count: int) -> bool:
        """Take the first `count` physics steps after a reset, with the commands set since, from memory.

        True when the World has restored where these steps ended before (time advances by `count`);
        False when the caller must take them with step(), in one call or several. A start is remembered
        the second time it is seen (up to MAX_REMEMBERED_STARTS of them), and only when nothing but
        commands changed between the reset and these steps, and nothing at all during them; never in a
        World with PyBullet's window, where the mouse can move the robot."""
        if not self._starts.at_reset:
            return False
        end = self._starts.replay(StartKey(count, tuple((c.command, c.running, c.memory) for c in self._controllers)),
                                  self.step_count)
        if end is None:
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

    def _save_start_end(self) -> _StartEnd:
        return _StartEnd(p.saveState(physicsClientId=self._cid), tuple(c.memory for c in self._controllers),
                         tuple(self._controller_efforts), self._substeps)

    def _discard_start_end(self, end: _StartEnd) -> None:
        p.removeState(end.state, physicsClientId=self._cid)

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

    @_changes(Change.COMMANDS)
    def start_controller(self, controller: str) -> None:
        """(Re)start a controller: a position controller holds the current position, a velocity one stops."""
        pid = self._controller_by_name[controller]
        pid.reset(p.getJointState(self._body, pid.joint_index, physicsClientId=self._cid)[0])
        pid.running = True

    @_changes(Change.COMMANDS)
    def stop_controller(self, controller: str) -> None:
        """Stop a controller: from the next step on it applies no effort and ignores commands."""
        self._controller_by_name[controller].running = False

    # -- physics properties (Gazebo's set_physics_properties) -----------------------------------
    @property
    def gravity(self) -> tuple[float, float, float]:
        return self._gravity

    @_changes(Change.PHYSICS)
    def set_gravity(self, gravity: Sequence[float]) -> None:
        """Set the gravity vector (m/s^2, world frame) from the next step on; resets keep it."""
        values = tuple(float(g) for g in gravity)
        if len(values) != 3 or not all(math.isfinite(g) for g in values):
            raise ValueError(f"gravity must be three finite numbers, got {tuple(gravity)!r}")
        p.setGravity(*values, physicsClientId=self._cid)
        self._gravity = values

    @_changes(Change.PHYSICS)
    def set_time_step(self, time_step: float) -> None:
        """Change the physics step (s) from the next step on; sim time stays continuous."""
        _check_time_step(time_step, ValueError)
        self.time_step = float(time_step)
        self._step_ns = round(self.time_step * 1e9)
        self._substeps = 1
        p.setPhysicsEngineParameter(fixedTimeStep=self.time_step, physicsClientId=self._cid)

    @property
    def solver(self) -> SolverSettings:
        return self._solver

    @_changes(Change.PHYSICS)
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

    # -- the attitude assist (not Gazebo's: a curriculum's help) ---------------------------------
    @property
    def attitude_assist(self) -> tuple[float, float]:
        """The assist's (stiffness N m/rad, damping N m s/rad); (0, 0): off."""
        return self._assist

    @_changes(Change.PHYSICS)
    def set_attitude_assist(self, stiffness: float, damping: float) -> None:
        """From the next step on, pull the base upright (module docstring); (0, 0) turns it off; resets keep it.
        ValueError for a gain that is not a finite number in [0, MAX_ASSIST_GAIN]."""
        for name, value in (("stiffness", stiffness), ("damping", damping)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0.0 <= value <= MAX_ASSIST_GAIN):
                raise ValueError(f"attitude assist {name} must be a finite number from 0 to {MAX_ASSIST_GAIN:g}, "
                                 f"got {value!r}")
        self._assist = (float(stiffness), float(damping))

    def _assist_torque(self) -> list[float]:
        """The assist's torque on the base now (world frame): stiffness x (base z cross world z), whose length is
        the sine of the tilt, minus damping x the horizontal angular velocity."""
        stiffness, damping = self._assist
        orientation = p.getBasePositionAndOrientation(self._body, physicsClientId=self._cid)[1]
        angular = p.getBaseVelocity(self._body, physicsClientId=self._cid)[1]
        z = rotate(orientation, (0.0, 0.0, 1.0))
        return [stiffness * z[1] - damping * angular[0], -stiffness * z[0] - damping * angular[1], 0.0]

    # -- Gazebo's set_model_state (its get_model_state and get_link_state: pybullet_sim.measurements) --
    @_changes(Change.STATE)
    def set_model_state(self, state: FrameState) -> None:
        """Move the robot's base frame to a pose with a twist (world frame); the joints keep their state.

        As Gazebo does, the orientation is normalised and an all-zero quaternion means no rotation.
        ValueError naming the field if a number is not finite or beyond the sim's bounds (validation)."""
        problem = frame_state_problem(state.position, state.orientation, state.linear_velocity, state.angular_velocity)
        if problem:
            raise ValueError(problem)
        orientation = normalized(state.orientation)
        inertial_position, inertial_orientation = p.getDynamicsInfo(self._body, -1, physicsClientId=self._cid)[3:5]
        com = tuple(a + b for a, b in zip(state.position, rotate(orientation, inertial_position), strict=True))
        com_orientation = quaternion_multiply(orientation, inertial_orientation)
        offset = tuple(a - b for a, b in zip(com, state.position, strict=True))
        spin = cross(state.angular_velocity, offset)
        com_velocity = tuple(v + w for v, w in zip(state.linear_velocity, spin, strict=True))
        p.resetBasePositionAndOrientation(self._body, com, com_orientation, physicsClientId=self._cid)
        p.resetBaseVelocity(self._body, com_velocity, state.angular_velocity, physicsClientId=self._cid)
        p.performCollisionDetection(physicsClientId=self._cid)
        self._imu_previous.clear()

    @_changes(Change.STATE)
    def set_joint_positions(self, positions: Mapping[str, float]) -> None:
        """Set movable joints to positions (rad or m), at rest (Gazebo's set_model_configuration); the base and
        the joints not named keep their state, the controllers their commands. ValueError, with nothing
        changed, for a joint that is not movable or a position that is not finite or outside the joint's URDF
        limits."""
        indices = {name: self._movable[slot] for slot, name in enumerate(self.joint_names)}
        for name, value in positions.items():
            if name not in indices:
                raise ValueError(f"no movable joint {name!r} (joints: {', '.join(self.joint_names)})")
            if not math.isfinite(value):
                raise ValueError(f"joint {name!r}: position must be a finite number, got {value!r}")
            lower, upper = p.getJointInfo(self._body, indices[name], physicsClientId=self._cid)[8:10]
            if lower <= upper and not lower <= value <= upper:  # a joint with limits (PyBullet: lower > upper if none)
                raise ValueError(f"joint {name!r}: position {value!r} is outside its URDF limits [{lower}, {upper}]")
        for name, value in positions.items():
            p.resetJointState(self._body, indices[name], float(value), 0.0, physicsClientId=self._cid)
        p.performCollisionDetection(physicsClientId=self._cid)
        self._imu_previous.clear()

    # -- resets ---------------------------------------------------------------------------------
    def _reset_controllers(self) -> None:
        """Restart every controller as gazebo_ros_control does on a reset; stopped ones stay stopped."""
        states = (p.getJointStates(self._body, self._controlled_indices, physicsClientId=self._cid)
                  if self._controllers else [])
        for controller, state in zip(self._controllers, states):
            controller.reset(state[0])
        self._controller_efforts = [0.0] * len(self._controllers)
        self._imu_previous.clear()

    @_changes(Change.RESET)
    def reset_world(self) -> None:
        """Back to the spawn pose at rest with controllers restarted; time keeps going."""
        p.restoreState(self._saved_state, physicsClientId=self._cid)
        # restoreState keeps the contact points of the last step: recompute them for the restored pose.
        p.performCollisionDetection(physicsClientId=self._cid)
        self._reset_controllers()

    @_changes(Change.RESET)
    def reset_simulation(self) -> None:
        """reset_world, plus time back to 0 and the noise generator restarted from the seed."""
        self.reset_world()
        self.step_count = 0
        self._time_ns = 0
        self._rng = np.random.default_rng(self.seed)

    def close(self) -> None:
        if self._scene is not None:
            self._scene.close()
            self._scene = None
        if self._cid >= 0:
            p.disconnect(self._cid)
            self._cid = -1

    # -- sensors (each kind's reader: pybullet_sim.measurements) ---------------------------------
    def read_joint_states(self) -> JointStateReading:
        states = p.getJointStates(self._body, self._movable, physicsClientId=self._cid)
        efforts = self._controller_efforts
        return JointStateReading(stamp=self.time, name=self.joint_names,
                                 position=tuple(s[0] for s in states), velocity=tuple(s[1] for s in states),
                                 effort=tuple(0.0 if slot is None else efforts[slot] for slot in self._effort_slots))

    def read_sensor(self, sensor: SensorConfig):
        """The reading of one configured sensor (odometry, IMU or contact)."""
        return SENSOR_KINDS[sensor.type].read(self, sensor)

    # -- rendering (the scene it is drawn in: pybullet_sim.scene) ---------------------------------
    def render(self, width: int, height: int) -> np.ndarray:
        """An RGB image (height x width x 3, uint8) from the camera of config.camera (following the base, its
        x and y, or fixed), with the scene's shadows, height poles and contact colours; drawn in a PyBullet
        client of its own (pybullet_sim.scene), so that it changes nothing here."""
        check_image_size(width, height)
        cid, body = self._cid, self._body
        contact_links = {self._link_index[s.link] for s in self.config.sensors if s.type == "contact"}
        if self._scene is None:
            self._scene = Scene(self._urdf_text, self.config, contact_links)
        touching = {link for link in contact_links
                    if p.getContactPoints(bodyA=body, linkIndexA=link, physicsClientId=cid)}
        states = p.getJointStates(body, self._movable, physicsClientId=cid)
        return self._scene.render(width, height, p.getBasePositionAndOrientation(body, physicsClientId=cid),
                                  [(index, state[0]) for index, state in zip(self._movable, states, strict=True)],
                                  touching)

    def aim_gui_camera(self) -> None:
        """Point the GUI window's camera (World(gui=True)) where render()'s camera looks."""
        camera = self.config.camera
        base = p.getBasePositionAndOrientation(self._body, physicsClientId=self._cid)[0]
        p.resetDebugVisualizerCamera(camera.distance, camera.yaw, camera.pitch,
                                     camera_target(camera, base, self.config.spawn_xyz), physicsClientId=self._cid)
