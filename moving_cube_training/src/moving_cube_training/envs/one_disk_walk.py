"""MovingCubeOneDiskWalk-v0: the moving cube learns to roll along world +y (openai_ros one_disk_walk).

Actions: Discrete(5)
    0  wheel command +roll_speed_fixed_value (rad/s)
    1  wheel command -roll_speed_fixed_value
    2  wheel command 0 (stop the wheel)
    3  previous command + roll_speed_increment_value
    4  previous command - roll_speed_increment_value
    Every command is clipped to +/-roll_speed_fixed_value.
Observation: Box(6,), float32
    0  wheel speed (rad/s, within the URDF limit +/-1000)
    1  y distance from init_cube_pose/y (m)
    2  roll, 3 pitch (rad; from the odometry quaternion, tf's euler_from_quaternion, axes sxyz)
    4  y speed (m/s)
    5  yaw (rad)
Reward: the sum of the terms, each in info as reward_<term>
    distance  (y - previous y) * move_distance_reward_weight
    speed     y speed * y_linear_speed_reward_weight
    yaw       -abs(sin(yaw)) * y_axis_angle_reward_weight
    fall      -end_episode_points, alone, on the step that ends the episode by a fall
Terminated: abs(pitch) > max_pitch_angle or abs(yaw) > max_yaw_angle (tipped sideways or turned away).
Truncated: after nsteps steps (gymnasium's TimeLimit; registered with 1000).
Step: the command is published and the sim advances running_step of sim time, in lockstep.
Info: y_travelled (m along +y since the episode started), fell, the reward terms, sim_time.
Metrics: y_distance (y_travelled at the end), success (y_distance >= 0.5 m).
Arguments: backend ("ros", "direct" or a Backend), params (CubeParams; default config/one_disk_walk.yaml),
    seed (the direct sim's noise), ros_timeout (s, every wait on the sim).

Fixes over the tutorial: the observation bounds are the real ranges (the tutorial bounded yaw with
max_y_linear_speed and roll with 2 pi); the wheel command does not block until the wheel reaches the
speed (that loop had no timeout and hung on a fallen cube); observations are not rounded (the
Q-learning state key makes the states); action 1 really is -fixed (one tutorial copy had +).
"""
from __future__ import annotations

import functools
import math

import numpy as np
from gymnasium import spaces
from tf.transformations import euler_from_quaternion

from robot_rl import Episode, MetricValue, Readings, RobotEnv, StepOutcome, TaskSpec

from ..params import N_ACTIONS, CubeParams
from ..robot import MOVING_CUBE, ODOMETRY_SENSOR, WHEEL_CONTROLLER, WHEEL_JOINT
from ..state import CubeStateKey

SUCCESS_DISTANCE = 0.5      # m along +y: an episode that ends this far along has succeeded


def cube_metrics(episode: Episode) -> dict[str, MetricValue]:
    """How far the episode rolled the cube along +y, and whether that is a success (>= 0.5 m)."""
    distance = float(episode.info.get("y_travelled", 0.0))
    return {"y_distance": distance, "success": distance >= SUCCESS_DISTANCE}


ONE_DISK_WALK = TaskSpec(
    name="one_disk_walk", env_id="MovingCubeOneDiskWalk-v0", entry_point=f"{__name__}:MovingCubeOneDiskWalkEnv",
    package="moving_cube_training", robot=MOVING_CUBE, params_type=CubeParams, params_namespace="/moving_cube",
    state_key=CubeStateKey, results_name="moving_cube", reward_topic="/moving_cube/reward",
    episode_reward_topic="/moving_cube/episode_reward", publish_cumulated_reward=False, max_episode_steps=1000,
    metrics=cube_metrics, headline_metric="success", eval_horizon_s=60.0)


class MovingCubeOneDiskWalkEnv(RobotEnv[CubeParams]):
    task = ONE_DISK_WALK

    @functools.cached_property
    def wheel_speed_limit(self) -> float:
        """rad/s: the URDF velocity limit of the wheel's joint (the sim enforces it)."""
        return self.task.robot.joints()[WHEEL_JOINT].velocity

    def _spaces(self) -> tuple[spaces.Discrete, spaces.Box]:
        high = np.array([self.wheel_speed_limit, np.inf, math.pi, math.pi / 2, np.inf, math.pi], dtype=np.float32)
        return spaces.Discrete(N_ACTIONS), spaces.Box(-high, high, dtype=np.float32)

    def _settle_time(self) -> float:
        return self.params.reset_settle_time

    def _reset_commands(self) -> None:
        self.wheel_command = self.params.init_roll_vel
        self.backend.set_command(WHEEL_CONTROLLER, self.wheel_command)

    def _start_episode(self, readings: Readings) -> None:
        y = readings.odometry(ODOMETRY_SENSOR).position[1]
        self.start_y = y
        self._previous_y = y - self.params.init_cube_pose.y

    def _apply_action(self, action: int, readings: Readings) -> None:
        p = self.params
        fixed, increment = p.roll_speed_fixed_value, p.roll_speed_increment_value
        command = (fixed, -fixed, 0.0, self.wheel_command + increment, self.wheel_command - increment)[action]
        self.wheel_command = min(max(command, -fixed), fixed)
        self.backend.set_command(WHEEL_CONTROLLER, self.wheel_command)

    def _observe(self, readings: Readings) -> np.ndarray:
        odom = readings.odometry(ODOMETRY_SENSOR)
        roll, pitch, yaw = euler_from_quaternion(odom.orientation)
        limit = self.wheel_speed_limit
        wheel_speed = min(max(readings.joints.velocity[0], -limit), limit)
        return np.array([wheel_speed, odom.position[1] - self.params.init_cube_pose.y, roll, pitch,
                         odom.linear_velocity[1], yaw], dtype=np.float32)

    def _reward_and_termination(self, observation: np.ndarray, readings: Readings) -> StepOutcome:
        p = self.params
        y_distance, pitch, y_speed, yaw = (float(observation[i]) for i in (1, 3, 4, 5))
        fell = abs(pitch) > p.max_pitch_angle or abs(yaw) > p.max_yaw_angle
        info = {"y_travelled": readings.odometry(ODOMETRY_SENSOR).position[1] - self.start_y, "fell": fell}
        if fell:
            return {"fall": -p.end_episode_points}, True, info
        terms = {"distance": (y_distance - self._previous_y) * p.move_distance_reward_weight,
                 "speed": y_speed * p.y_linear_speed_reward_weight,
                 "yaw": -abs(math.sin(yaw)) * p.y_axis_angle_reward_weight}
        self._previous_y = y_distance
        return terms, False, info
