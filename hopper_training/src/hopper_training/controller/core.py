"""A Raibert-style hopping controller for the monoped: three joint position targets from its sensor readings.

No ROS and no sim here: `HopController.update` takes plain values (`HopInput`: joint positions and velocities,
the IMU's orientation and body rates, the odometry's position and velocity, the foot's contact) and returns the
haa, hfe and kfe position targets that the tutorial's three `JointPositionController`s (effort PIDs p, d) track.
The ROS node (scripts/hop_controller.py), `evaluate.py --policy controller` and scripts/hop_stages.py wrap it.

Raibert's three parts (Raibert, Brown, Chepponis, IJRR 3(2) 1984), on a phase machine driven by the foot's
contact and the knee's rate:
  FLIGHT       -> (contact)                      LOADING (COMPRESSION if standing at the first reading)
  LOADING      -> (knee flexing)                 COMPRESSION
  COMPRESSION  -> (knee stops flexing)           THRUST
  THRUST       -> (knee near its thrust target)  UNLOADING
  any stance   -> (no contact for lift_off_s)    FLIGHT
- Hopping height: in FLIGHT the knee holds a landing crouch; at the bottom of stance (THRUST) its target
  steps towards straight, adapted once per hop to the apex measured in the last flight.
- Attitude: in stance the hips apply a torque that makes the ground force point at the robot's centre of
  mass (the knee's thrust then turns nothing), plus a PD on the body's tilt in COMPRESSION and THRUST. A
  torque reaches the joint through its known position PD: q_cmd = q + (tau + d * qdot) / p.
- Foot placement: in FLIGHT the foot goes to x_f = v * T_s / 2 + k_v * (v - v_d) + b from the centre of mass,
  along world x and y (T_s: the last stance time; Raibert's neutral point plus a speed correction; b: each
  touchdown adds k_i times the flight's mean speed error, which removes the steady speed error), the
  hips solving for the body's tilt and yaw (the hips cannot hold the yaw of a point foot: it drifts).
  Hooks for the hop_in_place task (envs/hop_in_place.py): `placement_offset` (m, world x, y) is added to the foot
  placement, and HopGains.speed_feedback False leaves out k_v (v - v_d) and b (the neutral point remains).
  For the residual tasks (envs/residual_in_place.py): `hip_offset` (rad, haa and hfe) is added to the flight's hip
  targets that the inverse kinematics solved for, before the swing gain.

The leg's kinematics and masses (LegModel) are hopper_description/urdf/monoped.urdf's; test_hop_controller.py
checks them against PyBullet's. Roll, pitch and yaw are sxyz Euler angles of the IMU's orientation, as tf's.
"""
from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pybullet_sim.readings import ContactReading, ImuReading, JointStateReading, OdometryReading

from ..robot import JOINTS

GRAVITY = 9.81
KNEE_LIMITS = (-1.6, 0.0)
HIP_LIMITS = (-1.6, 1.6)


class Phase(enum.Enum):
    FLIGHT = "flight"
    LOADING = "loading"
    COMPRESSION = "compression"
    THRUST = "thrust"
    UNLOADING = "unloading"


@dataclass(frozen=True)
class HopInput:
    """One snapshot of what the controller reads, as the tutorial's topics carry it."""

    time: float                              # s of sim time
    joint_position: Sequence[float]          # haa, hfe, kfe (rad)
    joint_velocity: Sequence[float]          # rad/s
    orientation: Sequence[float]             # the IMU's world orientation, quaternion x, y, z, w
    angular_velocity: Sequence[float]        # the IMU's body-frame rates (rad/s)
    position: Sequence[float]                # the odometry's base position (m, world)
    linear_velocity: Sequence[float]         # the odometry's base velocity (m/s, world)
    contact: bool                            # the foot touches the ground


def hop_input(joints: JointStateReading, imu: ImuReading, odometry: OdometryReading,
              contact: ContactReading) -> HopInput:
    """The controller's input from the monoped's four sensor readings (joints read by name)."""
    slots = [joints.name.index(name) for name in JOINTS]
    return HopInput(time=joints.stamp, joint_position=[joints.position[i] for i in slots],
                    joint_velocity=[joints.velocity[i] for i in slots], orientation=imu.orientation,
                    angular_velocity=imu.angular_velocity, position=odometry.position,
                    linear_velocity=odometry.linear_velocity, contact=bool(contact.contacts))


@dataclass(frozen=True)
class LegModel:
    """The monoped's geometry and masses (monoped.urdf), in the base frame: the haa axis runs along -x
    through (0, 0, haa_z); the hfe and kfe axes along +y; at zero angles the leg points straight down."""

    haa_z: float = -0.15            # m: the haa axis below the base's centre
    hip_length: float = 0.08        # m: haa axis -> hfe axis
    segment: float = 0.35           # m: hfe -> kfe and kfe -> foot centre
    base_mass: float = 0.4672
    hip_mass: float = 0.1168
    thigh_mass: float = 0.1168
    shank_mass: float = 0.0292

    @property
    def mass(self) -> float:
        return self.base_mass + self.hip_mass + self.thigh_mass + self.shank_mass

    def points(self, q: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """The foot centre and the whole robot's centre of mass in the base frame at joint angles q.
        Scalar arithmetic (the controller calls this ~10 times a control period): haa turns the leg's points,
        all in the base's x-z plane before the turn, about the -x axis through (0, 0, haa_z)."""
        haa, hfe, kfe = q
        hip_z = self.haa_z - self.hip_length
        thigh_x, thigh_z = -math.sin(hfe) * self.segment, -math.cos(hfe) * self.segment
        shank_x, shank_z = -math.sin(hfe + kfe) * self.segment, -math.cos(hfe + kfe) * self.segment
        knee_x, knee_z = thigh_x, hip_z + thigh_z
        foot_x, foot_z = knee_x + shank_x, knee_z + shank_z
        c, s = math.cos(-haa), math.sin(-haa)
        pivot = self.haa_z

        def turned(x: float, z: float) -> tuple[float, float, float]:
            return x, -s * (z - pivot), pivot + c * (z - pivot)
        parts = ((self.hip_mass, turned(0.0, hip_z + self.hip_length / 2.0)),
                 (self.thigh_mass, turned(thigh_x / 2.0, hip_z + thigh_z / 2.0)),
                 (self.shank_mass, turned(knee_x + shank_x / 2.0, knee_z + shank_z / 2.0)))
        com = [sum(mass * point[i] for mass, point in parts) / self.mass for i in range(3)]
        return np.array(turned(foot_x, foot_z)), np.array(com)  # the base's centre of mass is the origin

    def foot_from_com(self, q: Sequence[float]) -> np.ndarray:
        foot, com = self.points(q)
        return foot - com

    def jacobian(self, q: Sequence[float], of_com: bool = False) -> np.ndarray:
        """d(foot)/dq (3 x 3, base frame), or with `of_com` d(foot - com)/dq; forward differences."""
        def point(angles: Sequence[float]) -> np.ndarray:
            foot, com = self.points(angles)
            return foot - com if of_com else foot
        origin = point(q)
        columns = []
        for j in range(3):
            moved = list(q)
            moved[j] += 1e-6
            columns.append((point(moved) - origin) / 1e-6)
        return np.stack(columns, axis=1)


@dataclass(frozen=True)
class HopGains:
    """The controller's settings; each value's reason in docs/guide/hopping.md."""

    pid_p: float = 10.0              # the joints' position PID (hopper_sim.yaml), to turn torques into targets
    pid_d: float = 0.5
    landing_knee: float = -0.6       # rad: the knee's target in flight
    thrust_knee: float = 0.0         # rad: the knee's target in THRUST (adapted per hop when apex_target > 0)
    start_thrust_knee: float = -0.3  # rad: the first thrust's target when the robot stands at the start
    apex_target: float = 0.0         # m of base height at the apex to adapt the thrust to (0: fixed thrust)
    thrust_gain: float = 1.0         # rad of thrust target per m of apex error
    unload_margin: float = 0.1       # rad: THRUST -> UNLOADING when the knee is this close to its thrust target
    lift_off_s: float = 0.005        # s without contact before a stance phase counts as over
    attitude_kp: float = 3.0         # N m / rad of hip torque per rad of tilt in stance
    attitude_kd: float = 0.3         # N m s / rad of hip torque per rad/s of tilt rate
    force_through_com: bool = True   # stance hip torques that aim the ground force at the centre of mass
    flight_swing_gain: float = 3.0   # flight: 1 / (1 - r), r = leg / (leg + body) pitch inertia ~ 2/3 (est.)
    placement_kv: float = 0.2        # s: foot placement per m/s of speed error (Raibert's k)
    placement_ki: float = 0.03       # s: foot placement added each hop per m/s of that flight's speed error
    max_placement_bias: float = 0.06  # m: the most the per-hop sum may add
    stance_time: float = 0.15        # s: T_s before the first stance is measured
    max_foot_offset: float = 0.25    # m: the largest foot placement from under the centre of mass
    speed: tuple[float, float] = (0.0, 0.0)  # m/s commanded along world x and y
    speed_feedback: bool = True      # False: no k_v (v - v_d) and no per-hop sum b (the hop-level task learns them)
    neutral_point: bool = True       # False: no v T_s / 2 either (the foot goes under the centre of mass + offset)


def euler_sxyz(quaternion: Sequence[float]) -> tuple[float, float, float]:
    """Roll, pitch, yaw of a quaternion (x, y, z, w), as tf.transformations.euler_from_quaternion(q, 'sxyz')."""
    x, y, z, w = quaternion
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def level_rotation(roll: float, pitch: float) -> np.ndarray:
    """Base frame -> the level frame turned by the body's yaw: Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    return np.array([[cp, sp * sr, sp * cr], [0.0, cr, -sr], [-sp, cp * sr, cp * cr]])


def clamp(value: float, limits: tuple[float, float]) -> float:
    return min(max(value, limits[0]), limits[1])


def foot_placement(velocity: float, speed: float, stance_time: float, kv: float, limit: float) -> float:
    """Raibert's foot placement along one level axis (m ahead of the centre of mass): the neutral point
    v * T_s / 2 plus kv * (v - v_d), clamped to +/- limit."""
    return clamp(velocity * stance_time / 2.0 + kv * (velocity - speed), (-limit, limit))


def hips_for_foot(model: LegModel, target: Sequence[float], q: Sequence[float], rotation: np.ndarray,
                  iterations: int = 2) -> tuple[float, float]:
    """haa, hfe that put the foot at `target` (x, y from the centre of mass, level frame) with the knee at
    q[2] and the body turned by `rotation` (level_rotation); Newton steps from the hips of q."""
    haa, hfe, knee = q
    for _ in range(iterations):
        error = np.asarray(target[:2]) - (rotation @ model.foot_from_com((haa, hfe, knee)))[:2]
        jacobian = (rotation @ model.jacobian((haa, hfe, knee), of_com=True))[:2, :2]
        try:
            step = np.linalg.solve(jacobian, error)
        except np.linalg.LinAlgError:
            break
        haa = clamp(haa + float(step[0]), HIP_LIMITS)
        hfe = clamp(hfe + float(step[1]), HIP_LIMITS)
    return haa, hfe


@dataclass
class HopController:
    """The phase machine and its three laws; `update` once per control period, from the first reading on."""

    gains: HopGains = field(default_factory=HopGains)
    model: LegModel = field(default_factory=LegModel)
    phase: Phase = Phase.FLIGHT
    hops: int = 0                                # touchdowns seen
    thrust_knee: float = 0.0                     # the thrust target of this hop
    stance_time: float = 0.0                     # s, the last stance's
    apex: float = 0.0                            # m, the last flight's apex height of the base
    _started: bool = False                       # a reading has been seen
    _touchdown_time: float = 0.0
    _lost_contact_time: float | None = None
    placement_bias: list[float] = field(default_factory=lambda: [0.0, 0.0])  # m along world x, y: the per-hop sum
    placement_offset: list[float] = field(default_factory=lambda: [0.0, 0.0])  # m along world x, y, set from outside
    hip_offset: list[float] = field(default_factory=lambda: [0.0, 0.0])  # rad on the flight IK's haa, hfe, from outside
    _flight_energy: list[float] = field(default_factory=list)  # z + vz^2 / 2g of this flight's readings
    _flight_velocity: list[tuple[float, float]] = field(default_factory=list)  # vx, vy of this flight's readings

    def __post_init__(self) -> None:
        self.thrust_knee = self.gains.thrust_knee
        self.stance_time = self.gains.stance_time

    def reset(self) -> None:
        """Back to FLIGHT with nothing measured (a new episode)."""
        self.__init__(self.gains, self.model)  # type: ignore[misc]

    def update(self, reading: HopInput) -> tuple[float, float, float]:
        """The haa, hfe, kfe position targets (rad) for this reading."""
        self._advance_phase(reading)
        g = self.gains
        q, qd = list(reading.joint_position), list(reading.joint_velocity)
        roll, pitch, yaw = euler_sxyz(reading.orientation)
        rotation = level_rotation(roll, pitch)
        if self.phase is Phase.FLIGHT:
            self._flight_energy.append(reading.position[2] + reading.linear_velocity[2] ** 2 / (2.0 * GRAVITY))
            vx, vy = reading.linear_velocity[0], reading.linear_velocity[1]
            self._flight_velocity.append((vx, vy))
            kv = g.placement_kv if g.speed_feedback else 0.0
            stance_time = self.stance_time if g.neutral_point else 0.0
            world_target = (foot_placement(vx, g.speed[0], stance_time, kv, g.max_foot_offset)
                            + self.placement_bias[0] + self.placement_offset[0],
                            foot_placement(vy, g.speed[1], stance_time, kv, g.max_foot_offset)
                            + self.placement_bias[1] + self.placement_offset[1])
            target = (math.cos(yaw) * world_target[0] + math.sin(yaw) * world_target[1],
                      -math.sin(yaw) * world_target[0] + math.cos(yaw) * world_target[1])
            haa, hfe = hips_for_foot(self.model, target, (q[0], q[1], g.landing_knee), rotation)
            haa, hfe = haa + self.hip_offset[0], hfe + self.hip_offset[1]
            haa, hfe = (clamp(q[0] + g.flight_swing_gain * (haa - q[0]), HIP_LIMITS),
                        clamp(q[1] + g.flight_swing_gain * (hfe - q[1]), HIP_LIMITS))
            return haa, hfe, clamp(g.landing_knee, KNEE_LIMITS)
        knee_target = self.thrust_knee if self.phase in (Phase.THRUST, Phase.UNLOADING) else g.landing_knee
        torques = np.zeros(2)
        if g.force_through_com:
            torques += self._hip_torques_through_com(q, qd, knee_target, rotation)
        if self.phase in (Phase.COMPRESSION, Phase.THRUST):
            roll_rate, pitch_rate = reading.angular_velocity[0], reading.angular_velocity[1]
            torques += (-(g.attitude_kp * roll + g.attitude_kd * roll_rate),
                        g.attitude_kp * pitch + g.attitude_kd * pitch_rate)
        haa = self._target_for_torque(q[0], qd[0], float(torques[0]))
        hfe = self._target_for_torque(q[1], qd[1], float(torques[1]))
        return clamp(haa, HIP_LIMITS), clamp(hfe, HIP_LIMITS), clamp(knee_target, KNEE_LIMITS)

    def _hip_torques_through_com(self, q: Sequence[float], qd: Sequence[float], knee_target: float,
                                 rotation: np.ndarray) -> np.ndarray:
        """The haa, hfe torques under which the knee's torque now pushes the ground force along foot -> centre
        of mass (statics, tau = -J^T f u, the leg's own inertia left out)."""
        g = self.gains
        knee_torque = g.pid_p * (knee_target - q[2]) - g.pid_d * qd[2]
        foot, com = self.model.points(q)
        towards_com = (com - foot) / np.linalg.norm(com - foot)
        per_newton = -self.model.jacobian(q).T @ towards_com  # joint torques per N of ground force
        if abs(per_newton[2]) < 1e-3:
            return np.zeros(2)
        force = max(0.0, knee_torque / per_newton[2])
        return force * per_newton[:2]

    def _target_for_torque(self, position: float, velocity: float, torque: float) -> float:
        """The position command under which the joint's PD (p, d) applies `torque` now."""
        return position + (torque + self.gains.pid_d * velocity) / self.gains.pid_p

    def _advance_phase(self, reading: HopInput) -> None:
        g = self.gains
        started, self._started = self._started, True
        knee, knee_rate = reading.joint_position[2], reading.joint_velocity[2]
        if self.phase is Phase.FLIGHT:
            if reading.contact and not started:  # standing at the start: a gentle first thrust
                self.phase = Phase.COMPRESSION
                self.thrust_knee = g.start_thrust_knee
                self._touchdown_time = reading.time
            elif reading.contact:
                self.phase = Phase.LOADING
                if self.hops == 0:
                    self.thrust_knee = g.thrust_knee
                self.hops += 1
                self._touchdown_time = reading.time
                self._lost_contact_time = None
                if self._flight_energy:
                    self.apex = sum(self._flight_energy) / len(self._flight_energy)
                    if g.apex_target > 0.0:
                        self.thrust_knee = clamp(self.thrust_knee + g.thrust_gain * (g.apex_target - self.apex),
                                                 (g.landing_knee + 0.1, 0.0))
                self._flight_energy.clear()
                if self._flight_velocity:
                    for axis in (0, 1) if g.speed_feedback else ():
                        error = sum(v[axis] for v in self._flight_velocity) / len(self._flight_velocity) - g.speed[axis]
                        self.placement_bias[axis] = clamp(self.placement_bias[axis] + g.placement_ki * error,
                                                          (-g.max_placement_bias, g.max_placement_bias))
                    self._flight_velocity.clear()
            return
        if not reading.contact:
            if self._lost_contact_time is None:
                self._lost_contact_time = reading.time
            if reading.time - self._lost_contact_time >= g.lift_off_s - 1e-9:
                self.stance_time = reading.time - self._touchdown_time
                self.phase = Phase.FLIGHT
                return
        else:
            self._lost_contact_time = None
        if self.phase is Phase.LOADING and knee_rate < 0.0:
            self.phase = Phase.COMPRESSION
        elif self.phase is Phase.COMPRESSION and knee_rate >= 0.0:
            self.phase = Phase.THRUST
        elif self.phase is Phase.THRUST and knee >= self.thrust_knee - g.unload_margin:
            self.phase = Phase.UNLOADING
