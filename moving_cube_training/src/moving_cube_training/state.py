"""Q-learning state keys for the cube, made by robot_rl's Discretiser from four observation features.

The tutorial keyed states on str() of rounded wheel speed, y speed and yaw (so "-0.0" and "0.0"
were different states). Here the key is made of bins of:
- wheel speed: one bin per roll_speed_increment_value, centred on the speeds the actions reach;
- roll phase: roll folded onto the face the cube stands on, (roll + pi/4) mod pi/2 - pi/4. The
  cube rolls face to face, so where it is within a roll matters, not how many rolls it has made.
  Flat is |phase| < 0.08 rad: a cube still rocking after a landing must not look like one at rest;
- y speed: resting is |v_y| < 0.05 m/s (5 sigma of the odometry noise), then rolling back or
  forward, and the tails beyond 0.3 m/s;
- yaw: a dead band of max_yaw_angle/4 and tails beyond 0.75 max_yaw_angle: each landing turns the
  cube a little, and how far it has turned decides which moves are still safe.
With only wheel speed, y speed and yaw (the tutorial's choice) the start state and the state right
after a violent stop look alike, and the greedy policy learned to fall.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from robot_rl import Discretiser

from .params import CubeParams

FORMAT = "moving_cube_training.state_key/1"


def roll_phase(roll: float) -> float:
    """Roll folded onto the face the cube stands on, in [-pi/4, pi/4)."""
    return (roll + math.pi / 4) % (math.pi / 2) - math.pi / 4


class CubeStateKey:
    def __init__(self, params: CubeParams):
        fixed, increment = params.roll_speed_fixed_value, params.roll_speed_increment_value
        wheel_edges = np.arange(-fixed - increment / 2, fixed + increment, increment)
        yaw = params.max_yaw_angle
        self.discretiser = Discretiser.from_edges([
            wheel_edges,
            [-0.35, -0.08, 0.08, 0.35],
            [-0.3, -0.05, 0.05, 0.3],
            [-0.75 * yaw, -0.25 * yaw, 0.25 * yaw, 0.75 * yaw],
        ])

    def key(self, observation: np.ndarray) -> str:
        wheel_speed, _, roll, _, y_speed, yaw = (float(v) for v in observation)
        return self.discretiser.key([wheel_speed, roll_phase(roll), y_speed, yaw])

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "discretiser": self.discretiser.to_dict()}
