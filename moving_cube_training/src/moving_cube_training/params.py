"""The cube task's parameters: the tutorial's one_disk_walk_openai_params.yaml keys, under /moving_cube/.

Validated at start: a missing key, a wrong type or a value out of range stops with one line naming
the key and the file, and so does a key the params do not declare, but for the tutorial's unused keys
(pos_step, number_splits, max_distance, `TOLERATED_KEYS`): they may stay in the YAML; nothing reads them.
"""
from __future__ import annotations

from dataclasses import dataclass

from robot_rl import Point, TaskParams, param

N_ACTIONS = 5


@dataclass(frozen=True, kw_only=True)
class CubeParams(TaskParams):
    TOLERATED_KEYS = ("pos_step", "number_splits", "max_distance")  # the tutorial's, unused
    n_actions: int = param(low=N_ACTIONS, high=N_ACTIONS, doc="wheel +fixed, -fixed, stop, +increment, -increment")
    init_roll_vel: float = param(doc="wheel command at the start of an episode (rad/s)")
    roll_speed_fixed_value: float = param(low=0.0, low_open=True, doc="wheel command of actions 0/1, and its bound")
    roll_speed_increment_value: float = param(low=0.0, low_open=True, doc="wheel command change of actions 3/4")
    max_pitch_angle: float = param(low=0.0, low_open=True, doc="a fall: |pitch| beyond this (rad)")
    max_yaw_angle: float = param(low=0.0, low_open=True, doc="a fall: |yaw| beyond this (rad)")
    init_cube_pose: Point = param(doc="distances are measured along y from init_cube_pose/y")
    end_episode_points: float = param(doc="a fall gives -end_episode_points")
    move_distance_reward_weight: float
    y_linear_speed_reward_weight: float
    y_axis_angle_reward_weight: float
    reset_settle_time: float = param(low=0.0, doc="sim seconds the cube lands after a reset")
