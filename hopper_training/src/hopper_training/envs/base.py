"""The monoped env base every monoped task extends: the robot's start, joint targets, action interface (by
action_mode, hopper_training/actions.py), observation, hop tracking and metrics; a task adds its spec and reward."""
from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from gymnasium import spaces
from tf.transformations import quaternion_from_matrix

from pybullet_sim.readings import FrameState
from robot_rl import Episode, MetricValue, Placement, Readings, RobotEnv

from ..actions import ACTION_INTERFACES, ActionInterface
from ..hop_metrics import HopTracker
from ..kinematics import LegKinematics, leg_kinematics, tilt_rotation
from ..params import MonopedParams
from ..robot import (
    CONTROLLERS,
    IMU_SENSOR,
    JOINTS,
    ODOMETRY_SENSOR,
    base_rpy,
    contact_force,
    joint_positions,
    joint_velocities,
)


def monoped_metrics(episode: Episode) -> dict[str, MetricValue]:
    """Sim seconds the monoped stayed up, whether it stayed up until the end (and whether it fell), how far
    it moved along +x, and how it hopped (hopper_training/hop_metrics.py)."""
    info = episode.info
    return {"time_upright_s": episode.duration, "upright_whole_horizon": not episode.terminated,
            "fell": episode.terminated, "x_distance": float(info.get("x_travelled", 0.0)),
            "hops": float(info.get("hops", 0)), "apex_height": float(info.get("apex_height", 0.0)),
            "forward_speed": float(info.get("forward_speed", 0.0)),
            "lateral_drift": float(info.get("lateral_drift", 0.0))}


class MonopedBaseEnv(RobotEnv[MonopedParams]):
    """The monoped's env without a task: subclasses set `task` and give `_reward_and_termination`."""

    @functools.cached_property
    def joint_limits(self) -> tuple[tuple[float, float], ...]:
        """(lower, upper) of haa, hfe and kfe: the URDF's."""
        return self.task.robot.joint_limits(JOINTS)

    @functools.cached_property
    def kinematics(self) -> LegKinematics:
        """The leg's kinematics, from the URDF: where the foot is for the start pose."""
        return leg_kinematics(self.task.robot.urdf_path)

    @functools.cached_property
    def actions(self) -> ActionInterface:
        """The action interface the params' action_mode names."""
        return ACTION_INTERFACES[self.params.action_mode]

    @property
    def start_targets(self) -> list[float]:
        """The joint targets at reset: start_pose, or straight in action_mode tutorial."""
        return self.actions.start_targets(self.params)

    def _spaces(self) -> tuple[spaces.Discrete | spaces.Box, spaces.Box]:
        high = np.array([np.inf, math.pi, math.pi / 2, math.pi, np.inf, math.pi, math.pi, math.pi, np.inf, np.inf],
                        dtype=np.float32)
        low = -high
        low[[0, 4]] = 0.0
        if self.params.observation == "extended":
            limits = np.array(self.joint_limits, dtype=np.float32)
            low = np.concatenate([low, np.full(9, -np.inf, np.float32), [0.0], limits[:, 0]]).astype(np.float32)
            high = np.concatenate([high, np.full(9, np.inf, np.float32), [1.0], limits[:, 1]]).astype(np.float32)
        return self.actions.space(), spaces.Box(low, high, dtype=np.float32)

    def _start_placement(self) -> Placement | None:
        """The crouch (start_pose) with the foot on the ground, or the tutorial's straight leg at the spawn
        height; leaned about the foot by initial_tilt. None (the sim's spawn pose, untouched) for the tutorial
        without tilt."""
        tilt_range = self.params.initial_tilt
        straight = self.actions.straight_start
        tilt = float(self.np_random.uniform(tilt_range.low, tilt_range.high)) if tilt_range.high > 0.0 else 0.0
        heading = float(self.np_random.uniform(-math.pi, math.pi)) if tilt_range.high > 0.0 else 0.0
        if straight and tilt == 0.0:
            return None
        angles = dict(zip(JOINTS, self.start_targets))
        foot_in_base = self.kinematics.foot(angles)
        spawn = self.backend.config.spawn_xyz
        if straight:   # the foot stays where the spawn pose has it (5 cm above the ground)
            foot = np.array([spawn[0], spawn[1], spawn[2] + foot_in_base[2]])
        else:
            foot = np.array([spawn[0], spawn[1], self.kinematics.foot_radius])
        rotation = np.eye(4)
        rotation[:3, :3] = tilt_rotation(tilt, heading)
        base = foot - rotation[:3, :3] @ foot_in_base
        state = FrameState(tuple(base), tuple(quaternion_from_matrix(rotation)), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        return state, angles

    def _reset_commands(self) -> None:
        self.targets = self.start_targets
        for controller, target in zip(CONTROLLERS, self.targets):
            self.backend.set_command(controller, target)

    def _start_episode(self, readings: Readings) -> None:
        position = readings.odometry(ODOMETRY_SENSOR).position
        self.start_x = position[0]
        self.hop_tracker = HopTracker(self.running_step)
        self.hop_tracker.reset(readings.stamp, position, contact_force(readings) > 0.0)

    def _clamp(self, joint: int, target: float) -> float:
        low, high = self.joint_limits[joint]
        return min(max(target, low), high)

    def _apply_action(self, action: Any, readings: Readings) -> None:
        self.targets = self.actions.targets(action, readings, self.targets, self.start_targets, self.params,
                                            self._clamp)
        for controller, target in zip(CONTROLLERS, self.targets):
            self.backend.set_command(controller, target)

    def _observe(self, readings: Readings) -> np.ndarray:
        imu = readings.imu(IMU_SENSOR)
        roll_rate, pitch_rate, _ = imu.angular_velocity
        force = contact_force(readings)
        values = [self._distance_from_desired_pose(readings), *base_rpy(readings), force,
                  *joint_positions(readings), roll_rate, pitch_rate]
        if self.params.observation == "extended":
            values += [*joint_velocities(readings), *readings.odometry(ODOMETRY_SENSOR).linear_velocity,
                       *imu.angular_velocity, 1.0 if force > 0.0 else 0.0, *self.targets]
        return np.array(values, dtype=np.float32)

    def _distance_from_desired_pose(self, readings: Readings) -> float:
        desired = self.params.desired_pose
        return math.dist(readings.odometry(ODOMETRY_SENSOR).position, (desired.x, desired.y, desired.z))
