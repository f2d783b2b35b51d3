"""The monoped's parameters: seed 001's qlearn_params.yaml keys, at the root namespace.

Validated at start: a missing key, a wrong type or a value out of range stops with one line naming
the key and the file.
"""
from __future__ import annotations

from dataclasses import dataclass

from robot_rl.params import ParamError, Point, TaskParams, param


@dataclass(frozen=True, kw_only=True)
class MonopedParams(TaskParams):
    desired_pose: Point = param(doc="the base is rewarded for staying near this world point (m)")
    desired_force: float = param(low=0.0, low_open=True, doc="foot contact force of the robot standing still (N)")
    desired_yaw: float = param(doc="rad")
    max_height: float = param(doc="a fall: base height at or above this (m)")
    min_height: float = param(doc="a fall: base height below this (m)")
    max_incl: float = param(low=0.0, low_open=True, doc="a fall: |roll| or |pitch| at or beyond this (rad)")
    joint_increment_value: float = param(low=0.0, low_open=True, doc="joint target change of one action (rad)")
    done_reward: float = param(doc="the reward of a fall")
    alive_reward: float = param(doc="the reward of a step upright, before the penalties")
    weight_r1: float = param(doc="penalty weight of sum |joint position|")
    weight_r2: float = param(doc="penalty weight of sum |joint effort|")
    weight_r3: float = param(doc="penalty weight of | |contact force| - desired_force |")
    weight_r4: float = param(doc="penalty weight of |roll| + |pitch| + |yaw - desired_yaw|")
    weight_r5: float = param(doc="penalty weight of the distance from desired_pose")
    state_key: str = param(choices=("tilt", "tutorial"), default="tutorial",
                           doc="the Q-learning state key: tilt (TiltStateKey) or the tutorial's 10 bins")

    def check(self, source: str) -> None:
        if not self.min_height < self.max_height:
            raise ParamError(f"{source}: parameter 'min_height' ({self.min_height}) must be below "
                             f"'max_height' ({self.max_height})")
