"""MovingCubeOneDiskWalk-v0: the moving cube learns to roll along world +y (openai_ros one_disk_walk).

| | |
|---|---|
| Actions (Discrete 5) | 0: wheel +roll_speed_fixed_value, 1: wheel -fixed, 2: stop the wheel, 3: previous command +roll_speed_increment_value, 4: previous command -increment; always clipped to +/-fixed |
| Observation (float32 Box 6) | wheel speed (rad/s), y distance from init_cube_pose/y (m), roll, pitch (rad), y speed (m/s), yaw (rad); roll/pitch/yaw from the odom quaternion (tf, axes sxyz) |
| Reward | dy * move_distance_reward_weight + v_y * y_linear_speed_reward_weight - abs(sin(yaw)) * y_axis_angle_reward_weight; -end_episode_points on a fall |
| Terminated | abs(pitch) > max_pitch_angle or abs(yaw) > max_yaw_angle (the cube tipped sideways or turned away) |
| Truncated | after nsteps steps |
| Step | the command is published and the sim advances running_step of sim time, in lockstep |

Fixes over the tutorial: the observation bounds are the real ranges (the tutorial bounded yaw with
max_y_linear_speed and roll with 2 pi); the wheel command does not block until the wheel reaches the
speed (that loop had no timeout and hung on a fallen cube); observations are not rounded (the
Q-learning discretiser makes the states); action 1 really is -fixed (one tutorial copy had +).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

import numpy as np
from gymnasium import spaces
from tf.transformations import euler_from_quaternion

from robot_rl.backends import Backend, Readings, make_backend
from robot_rl.env_base import RobotEnv
from .params import load_default_params

REPO = Path(__file__).resolve().parents[3]
URDF = REPO / "moving_cube_description" / "urdf" / "moving_cube.urdf"
SIM_CONFIG = REPO / "config" / "moving_cube_sim.yaml"
WHEEL_CONTROLLER = "inertia_wheel_roll_joint_velocity_controller"
ODOMETRY_SENSOR = "p3d_base_controller"
WHEEL_SPEED_LIMIT = 1000.0  # rad/s, the URDF velocity limit of inertia_wheel_roll_joint (the sim enforces it)
N_ACTIONS = 5


class MovingCubeOneDiskWalkEnv(RobotEnv):
    def __init__(self, backend: str | Backend = "ros", params: Optional[Dict[str, Any]] = None,
                 seed: Optional[int] = None, ros_timeout: float = 10.0):
        """`params`: the validated /moving_cube/ params (default: config/moving_cube_qlearn.yaml).
        `backend`: "ros" (a running sim node), "direct" (in-process World seeded with `seed`) or a Backend."""
        self.params = dict(params) if params is not None else load_default_params()
        super().__init__(make_backend(backend, URDF, SIM_CONFIG, seed=seed, timeout=ros_timeout),
                         running_step=self.params["running_step"], max_episode_steps=self.params["nsteps"],
                         settle_time=self.params["reset_settle_time"])
        if self.params["n_actions"] != N_ACTIONS:
            raise ValueError(f"n_actions must be {N_ACTIONS} for this task, got {self.params['n_actions']}")
        self.action_space = spaces.Discrete(N_ACTIONS)
        high = np.array([WHEEL_SPEED_LIMIT, np.inf, math.pi, math.pi / 2, np.inf, math.pi], dtype=np.float32)
        self.observation_space = spaces.Box(-high, high, dtype=np.float32)
        self.wheel_command = 0.0
        self.start_y = 0.0
        self._previous_y = 0.0

    def _reset_commands(self) -> None:
        self.wheel_command = float(self.params["init_roll_vel"])
        self.backend.set_command(WHEEL_CONTROLLER, self.wheel_command)

    def _start_episode(self, readings: Readings) -> None:
        odom = readings.sensors[ODOMETRY_SENSOR]
        self.start_y = odom.position[1]
        self._previous_y = odom.position[1] - self.params["init_cube_pose/y"]

    def _apply_action(self, action: int) -> None:
        fixed = self.params["roll_speed_fixed_value"]
        increment = self.params["roll_speed_increment_value"]
        command = (fixed, -fixed, 0.0, self.wheel_command + increment, self.wheel_command - increment)[action]
        self.wheel_command = min(max(command, -fixed), fixed)
        self.backend.set_command(WHEEL_CONTROLLER, self.wheel_command)

    def _observe(self, readings: Readings) -> np.ndarray:
        odom = readings.sensors[ODOMETRY_SENSOR]
        roll, pitch, yaw = euler_from_quaternion(odom.orientation)
        wheel_speed = min(max(readings.joints.velocity[0], -WHEEL_SPEED_LIMIT), WHEEL_SPEED_LIMIT)
        return np.array([wheel_speed, odom.position[1] - self.params["init_cube_pose/y"], roll, pitch,
                         odom.linear_velocity[1], yaw], dtype=np.float32)

    def _reward_and_termination(self, observation: np.ndarray) -> Tuple[float, bool, Dict[str, Any]]:
        p = self.params
        y_distance, pitch, y_speed, yaw = (float(observation[i]) for i in (1, 3, 4, 5))
        fell = abs(pitch) > p["max_pitch_angle"] or abs(yaw) > p["max_yaw_angle"]
        info = {"y_travelled": self.readings.sensors[ODOMETRY_SENSOR].position[1] - self.start_y, "fell": fell}
        if fell:
            return -p["end_episode_points"], True, info
        reward = ((y_distance - self._previous_y) * p["move_distance_reward_weight"]
                  + y_speed * p["y_linear_speed_reward_weight"]
                  - abs(math.sin(yaw)) * p["y_axis_angle_reward_weight"])
        self._previous_y = y_distance
        return reward, False, info
