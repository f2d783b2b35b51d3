"""Policies that need no training: a robot package's scripted ones, constant actions, uniformly random actions.

A policy is a function observation -> action (an int for Discrete actions, an array for Box ones); a
`PolicyMaker` makes one for an env (the env it acts in, the seed of its tie breaks), as a trained run's
loader does (robot_rl.agents).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from .task import TaskSpec

Policy = Callable[[np.ndarray], Any]  # observation -> action (an int for Discrete, an array for Box)
PolicyMaker = Callable[[Any, int], Policy]  # (the env the policy acts in, the seed of its tie breaks) -> policy


@dataclass(frozen=True)
class ScriptedPolicy:
    """A hand-written policy a robot package offers to evaluate.py (`--policy NAME`): `env_params` turns a
    task's params into those its env needs; `build(env, speed)` makes the policy (observation -> action),
    which may read env.unwrapped.readings and, if it has a reset(), is reset at each episode's start."""

    env_params: Callable[[TaskSpec[Any], Any], Any]
    build: Callable[[Any, float], Callable[[np.ndarray], Any]]


class ConstantAction:
    """A policy that always takes one action: the trivial baselines (`--policy constant --action N`, and a robot
    package's do-nothing action)."""

    def __init__(self, action: Any):
        self.action = action

    def __call__(self, observation: np.ndarray) -> Any:
        return self.action


def constant_policy(action: str) -> ScriptedPolicy:
    """`--policy constant --action A`: action A every step: an index N for Discrete actions, comma-separated numbers
    (one per dimension, within the bounds) for Box actions."""
    def build(env: Any, speed: float) -> ConstantAction:
        space, env_id = env.action_space, env.unwrapped.task.env_id
        if speed != 0.0:
            raise ValueError(f"--policy constant takes no --speed, got {speed}")
        if isinstance(space, gymnasium.spaces.Discrete):
            if not action.strip().lstrip("-").isdigit() or not 0 <= int(action) < int(space.n):
                raise ValueError(f"--action must be from 0 to {int(space.n) - 1} ({env_id}'s "
                                 f"Discrete({int(space.n)})), got {action}")
            return ConstantAction(int(action))
        if not isinstance(space, gymnasium.spaces.Box) or len(space.shape) != 1:
            raise ValueError(f"--policy constant needs Discrete or one-dimensional Box actions; {env_id}'s are {space}")
        try:
            vector = np.array([float(value) for value in action.split(",")], dtype=space.dtype)
        except ValueError:
            vector = np.array([])
        if vector.shape != space.shape or not space.contains(vector):
            raise ValueError(f"--action must be {space.shape[0]} comma-separated numbers within {env_id}'s {space}, "
                             f"got {action}")
        return ConstantAction(vector)
    return ScriptedPolicy(lambda task, params: params, build)


def random_actions(space: Any, rng: np.random.Generator) -> Callable[[np.ndarray], Any]:
    """Uniformly random actions of a Discrete or Box action space, drawn from `rng`."""
    if isinstance(space, gymnasium.spaces.Discrete):
        return lambda _: int(rng.integers(int(space.n)))
    return lambda _: rng.uniform(space.low, space.high).astype(space.dtype)
