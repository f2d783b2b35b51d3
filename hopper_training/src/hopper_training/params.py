"""The monoped's parameters: seed 001's qlearn_params.yaml keys, at the root namespace.

Validated at start: a missing key, a wrong type or a value out of range stops with one line naming
the key and the file.
"""
from __future__ import annotations

from dataclasses import dataclass

from robot_rl import ParamError, Params, Point, TaskParams, param

from .robot import JOINTS, MONOPED

ACTION_MODES = ("accumulate", "tutorial", "targets")  # the names of actions.ACTION_INTERFACES
OBSERVATIONS = ("standard", "extended")


@dataclass(frozen=True, kw_only=True)
class JointPose(Params):
    """haa, hfe and kfe angles (rad)."""

    haa: float
    hfe: float
    kfe: float


@dataclass(frozen=True, kw_only=True)
class TiltRange(Params):
    """The range of a random tilt (rad)."""

    low: float = param(low=0.0, high=0.5)
    high: float = param(low=0.0, high=0.5)


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
    # Absent (the params.yaml of a run from before these keys): the tutorial's rule and straight leg, as trained.
    action_mode: str = param(choices=ACTION_MODES, default="tutorial",
                             doc="accumulate: Discrete(7) steps on the last commanded targets, 6 holds; tutorial: "
                                 "Discrete(6) steps on the measured positions, straight start; targets: Box(3) "
                                 "of absolute targets about start_pose")
    start_pose: JointPose = param(default=JointPose(haa=0.0, hfe=0.0, kfe=0.0),
                                  doc="joint angles at reset (rad), foot on the ground (not in action_mode tutorial)")
    target_range: float = param(low=0.0, low_open=True, high=3.2, default=1.0,
                                doc="action_mode targets: an action of +/-1 is start_pose +/- this (rad)")
    observation: str = param(choices=OBSERVATIONS, default="standard",
                             doc="standard: the 10 values; extended: also joint and base velocities, contact, "
                                 "the last targets")
    initial_tilt: TiltRange = param(default=TiltRange(low=0.0, high=0.0),
                                    doc="at reset the robot leans about its foot by a random angle in [low, "
                                        "high] (rad) in a random direction")

    def check(self, source: str) -> None:
        super().check(source)
        if not self.min_height < self.max_height:
            raise ParamError(f"{source}: parameter 'min_height' ({self.min_height}) must be below "
                             f"'max_height' ({self.max_height})")
        if not self.initial_tilt.low <= self.initial_tilt.high:
            raise ParamError(f"{source}: parameter 'initial_tilt/low' ({self.initial_tilt.low}) must not be above "
                             f"'initial_tilt/high' ({self.initial_tilt.high})")
        for name, (low, high) in zip(JOINTS, MONOPED.joint_limits(JOINTS)):
            key = name.removesuffix("_joint")
            value = getattr(self.start_pose, key)
            if not low <= value <= high:
                raise ParamError(f"{source}: parameter 'start_pose/{key}' = {value!r} is outside the URDF's limits "
                                 f"of {name} [{low}, {high}]")
