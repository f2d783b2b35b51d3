"""The monoped's action interfaces, by the params' action_mode: each gives its action space, the joint targets at
reset and how an action becomes the three targets. ACTION_INTERFACES holds them by name; adding one is one entry."""
from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from robot_rl import Readings

from .params import ACTION_MODES, MonopedParams
from .robot import JOINTS, joint_positions

HOLD = 6  # action_mode accumulate: the action that keeps the targets

Clamp = Callable[[int, float], float]  # (joint index, target) -> the target inside the joint's URDF limits


@dataclass(frozen=True)
class ActionInterface(abc.ABC):
    """One action_mode."""

    name: str
    straight_start: bool = False  # the robot starts straight at the sim's spawn pose; start_pose is not used

    @abc.abstractmethod
    def space(self) -> spaces.Discrete | spaces.Box:
        """The env's action space."""

    def start_targets(self, params: MonopedParams) -> list[float]:
        """The joint targets at reset: start_pose."""
        pose = params.start_pose
        return [pose.haa, pose.hfe, pose.kfe]

    @abc.abstractmethod
    def targets(self, action: Any, readings: Readings, last: list[float], start: list[float],
                params: MonopedParams, clamp: Clamp) -> list[float]:
        """The targets of `action`, given the last commanded targets and those at reset."""


def _stepped(action: int, targets: list[float], params: MonopedParams, clamp: Clamp) -> list[float]:
    """Actions 0-5: haa, hfe or kfe target +/- joint_increment_value, clamped."""
    joint, direction = divmod(action, 2)
    step = params.joint_increment_value * (1 - 2 * direction)
    targets[joint] = clamp(joint, targets[joint] + step)
    return targets


class AccumulateActions(ActionInterface):
    """Discrete(7): actions 0-5 step the last *commanded* targets, HOLD keeps them."""

    def space(self) -> spaces.Discrete:
        return spaces.Discrete(2 * len(JOINTS) + 1)

    def targets(self, action: Any, readings: Readings, last: list[float], start: list[float],
                params: MonopedParams, clamp: Clamp) -> list[float]:
        return last if action == HOLD else _stepped(action, list(last), params, clamp)


class TutorialActions(ActionInterface):
    """Discrete(6): actions 0-5 step the *measured* joint positions (the tutorial's rule); a straight start."""

    def space(self) -> spaces.Discrete:
        return spaces.Discrete(2 * len(JOINTS))

    def start_targets(self, params: MonopedParams) -> list[float]:
        return [0.0] * len(JOINTS)

    def targets(self, action: Any, readings: Readings, last: list[float], start: list[float],
                params: MonopedParams, clamp: Clamp) -> list[float]:
        return _stepped(action, joint_positions(readings), params, clamp)


class TargetsActions(ActionInterface):
    """Box(3) in [-1, 1]: absolute targets start + action * target_range, clamped."""

    def space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, shape=(len(JOINTS),), dtype=np.float32)

    def targets(self, action: Any, readings: Readings, last: list[float], start: list[float],
                params: MonopedParams, clamp: Clamp) -> list[float]:
        return [clamp(j, start[j] + float(action[j]) * params.target_range) for j in range(len(JOINTS))]


ACTION_INTERFACES: dict[str, ActionInterface] = {interface.name: interface for interface in (
    AccumulateActions("accumulate"), TutorialActions("tutorial", straight_start=True), TargetsActions("targets"))}
if tuple(ACTION_INTERFACES) != ACTION_MODES:
    raise ImportError(f"params.ACTION_MODES {ACTION_MODES} differ from the interfaces {tuple(ACTION_INTERFACES)}")
