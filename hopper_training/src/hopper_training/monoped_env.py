"""Monoped-v0: the hopper learns to stay up (seed 001's MonopedEnv, on the gymnasium 1.x API).

Actions: Discrete(6)
    0/1  haa target +/- joint_increment_value (rad)
    2/3  hfe target +/- joint_increment_value
    4/5  kfe target +/- joint_increment_value
    From the current joint positions, clamped to the URDF limits; the other two joints are commanded
    to stay where they are.
Observation: Box(10,), float32 (the tutorial's 8 in its order, then the tilt rates)
    0  distance of the base from desired_pose (m)
    1  roll, 2 pitch, 3 yaw of the base (rad, from the IMU)
    4  foot contact force (N, 0 in the air)
    5  haa, 6 hfe, 7 kfe positions (rad)
    8  roll rate, 9 pitch rate (rad/s: the IMU's angular velocity about the base's x and y axes)
State key (Q-learning; the params' state_key)
    tilt      (config/stay_up.yaml) forward or backward (the sign of pitch), how far the base leans
              (max(abs(roll), abs(pitch)) in decades, 1e-6 .. 0.1 rad), how fast (max of the abs tilt
              rates in decades, 1e-6 .. 1 rad/s), the knee (edges -0.3, -0.02 rad) and the foot's contact
              (force > 0): 2 x 7 x 8 x 3 x 2 keys (hopper_training/state.py: TiltStateKey)
    tutorial  the tutorial's: observations 0-7 in 10 linspace bins each (TutorialStateKey)
Reward: the sum of the terms, each in info as reward_<term>
    alive           alive_reward
    joint_position  -weight_r1 * sum of abs(joint positions)
    joint_effort    -weight_r2 * sum of abs(joint efforts)
    contact_force   -weight_r3 * abs(abs(contact force) - desired_force)
    orientation     -weight_r4 * (abs(roll) + abs(pitch) + abs(yaw - desired_yaw))
    distance        -weight_r5 * distance from desired_pose
    fall            done_reward, alone, on the step that ends the episode by a fall
Terminated: base height outside [min_height, max_height), or abs(roll) or abs(pitch) >= max_incl.
Truncated: after nsteps steps (gymnasium's TimeLimit; registered with 500: 10 s at 20 ms).
Step: the three joint targets are published and the sim advances running_step of sim time, in lockstep.
Info: fell, base_height (m), x_travelled (m of the base along +x since the episode started), the reward
    terms, sim_time.
Metrics: time_upright_s (sim seconds until the fall or the end), upright_whole_horizon (no fall),
    x_distance (x_travelled at the end).
Arguments: backend ("ros", "direct" or a Backend), params (MonopedParams; default config/stay_up.yaml),
    seed (the direct sim's noise), ros_timeout (s, every wait on the sim).

Fixes over the tutorial: an observation_space (gymnasium's env checker failed on its absence), the
5-tuple step and reset(seed=, options=), no time.sleep(running_step) of wall time between unpause
and pause (the sim advances exactly running_step), no gravity switching during reset, a TimeLimit
that matches nsteps (the tutorial registered 50 steps), the contact force drops to 0 when the foot
leaves the ground (the tutorial kept the last value), and joint targets stay inside the URDF limits.
"""
from __future__ import annotations

import functools
import math
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from tf.transformations import euler_from_quaternion

from robot_rl.backends import Readings
from robot_rl.env_base import RobotEnv, StepOutcome
from robot_rl.task import Episode, MetricValue, RobotSpec, TaskSpec

from .params import MonopedParams
from .state import monoped_state_key

CONTROLLERS = ("haa_joint_position_controller", "hfe_joint_position_controller", "kfe_joint_position_controller")
JOINTS = ("haa_joint", "hfe_joint", "kfe_joint")
ODOMETRY_SENSOR = "p3d_base_controller"
IMU_SENSOR = "gazebo_ros_imu_controller"
CONTACT_SENSOR = "lowerleg_contactsensor_sensor"

MONOPED = RobotSpec(description_package="hopper_description", urdf="urdf/monoped.urdf",
                    sim_config="config/hopper_sim.yaml", sim_launch="roslaunch pybullet_sim hopper_sim.launch")


def monoped_metrics(episode: Episode) -> dict[str, MetricValue]:
    """Sim seconds the monoped stayed up, whether it stayed up until the end, how far it moved along +x."""
    return {"time_upright_s": episode.duration, "upright_whole_horizon": not episode.terminated,
            "x_distance": float(episode.info.get("x_travelled", 0.0))}


STAY_UP = TaskSpec(
    name="stay_up", env_id="Monoped-v0", entry_point=f"{__name__}:MonopedEnv", package="hopper_training",
    robot=MONOPED, params_type=MonopedParams, params_namespace="/", state_key=monoped_state_key,
    results_name="monoped", reward_topic="/monoped/reward", episode_reward_topic="/monoped/episode_reward",
    publish_cumulated_reward=True, max_episode_steps=500, metrics=monoped_metrics,
    headline_metric="time_upright_s", eval_horizon_s=10.0)


def joint_positions(readings: Readings) -> list[float]:
    """haa, hfe, kfe positions, read by name."""
    joints = readings.joints
    return [joints.position[joints.name.index(name)] for name in JOINTS]


def base_rpy(readings: Readings) -> tuple[float, float, float]:
    """The base's roll, pitch and yaw from the IMU (tf's euler_from_quaternion, axes sxyz)."""
    roll, pitch, yaw = euler_from_quaternion(readings.imu(IMU_SENSOR).orientation)
    return roll, pitch, yaw


def contact_force(readings: Readings) -> float:
    """abs(total_wrench.force) of the foot's contact; 0 in the air."""
    contact = readings.contact(CONTACT_SENSOR)
    return math.hypot(*contact.total_force) if contact.contacts else 0.0


class MonopedEnv(RobotEnv[MonopedParams]):
    task: ClassVar[TaskSpec[Any]] = STAY_UP

    @functools.cached_property
    def joint_limits(self) -> tuple[tuple[float, float], ...]:
        """(lower, upper) of haa, hfe and kfe: the URDF's."""
        return self.task.robot.joint_limits(JOINTS)

    def _spaces(self) -> tuple[spaces.Discrete, spaces.Box]:
        high = np.array([np.inf, math.pi, math.pi / 2, math.pi, np.inf, math.pi, math.pi, math.pi, np.inf, np.inf],
                        dtype=np.float32)
        low = -high
        low[[0, 4]] = 0.0
        return spaces.Discrete(2 * len(JOINTS)), spaces.Box(low, high, dtype=np.float32)

    def _reset_commands(self) -> None:
        for controller in CONTROLLERS:
            self.backend.set_command(controller, 0.0)

    def _start_episode(self, readings: Readings) -> None:
        self.start_x = readings.odometry(ODOMETRY_SENSOR).position[0]

    def _apply_action(self, action: int, readings: Readings) -> None:
        targets = joint_positions(readings)
        joint, direction = divmod(action, 2)
        low, high = self.joint_limits[joint]
        targets[joint] = min(max(targets[joint] + self.params.joint_increment_value * (1 - 2 * direction), low), high)
        for controller, target in zip(CONTROLLERS, targets):
            self.backend.set_command(controller, target)

    def _observe(self, readings: Readings) -> np.ndarray:
        roll_rate, pitch_rate, _ = readings.imu(IMU_SENSOR).angular_velocity
        return np.array([self._distance_from_desired_pose(readings), *base_rpy(readings), contact_force(readings),
                         *joint_positions(readings), roll_rate, pitch_rate], dtype=np.float32)

    def _distance_from_desired_pose(self, readings: Readings) -> float:
        desired = self.params.desired_pose
        return math.dist(readings.odometry(ODOMETRY_SENSOR).position, (desired.x, desired.y, desired.z))

    def _reward_and_termination(self, observation: np.ndarray, readings: Readings) -> StepOutcome:
        p = self.params
        roll, pitch, yaw = base_rpy(readings)
        position = readings.odometry(ODOMETRY_SENSOR).position
        height_ok = p.min_height <= position[2] < p.max_height
        fell = not (height_ok and abs(roll) < p.max_incl and abs(pitch) < p.max_incl)
        info: dict[str, Any] = {"fell": fell, "base_height": position[2], "x_travelled": position[0] - self.start_x}
        if fell:
            return {"fall": p.done_reward}, True, info
        terms = {"alive": p.alive_reward,
                 "joint_position": -p.weight_r1 * sum(abs(q) for q in readings.joints.position),
                 "joint_effort": -p.weight_r2 * sum(abs(e) for e in readings.joints.effort),
                 "contact_force": -p.weight_r3 * abs(contact_force(readings) - p.desired_force),
                 "orientation": -p.weight_r4 * (abs(roll) + abs(pitch) + abs(yaw - p.desired_yaw)),
                 "distance": -p.weight_r5 * self._distance_from_desired_pose(readings)}
        return terms, False, info
