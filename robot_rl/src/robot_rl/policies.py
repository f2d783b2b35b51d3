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

    def __init__(self, action: int):
        self.action = action

    def __call__(self, observation: np.ndarray) -> int:
        return self.action


def constant_policy(action: int) -> ScriptedPolicy:
    """`--policy constant --action N`: action N every step, on any task with Discrete actions."""
    def build(env: Any, speed: float) -> ConstantAction:
        space = env.action_space
        if not isinstance(space, gymnasium.spaces.Discrete):
            raise ValueError(f"--policy constant needs Discrete actions; {env.unwrapped.task.env_id}'s are {space}")
        if not 0 <= action < int(space.n):
            raise ValueError(f"--action must be from 0 to {int(space.n) - 1} ({env.unwrapped.task.env_id}'s "
                             f"Discrete({int(space.n)})), got {action}")
        if speed != 0.0:
            raise ValueError(f"--policy constant takes no --speed, got {speed}")
        return ConstantAction(action)
    return ScriptedPolicy(lambda task, params: params, build)


def random_actions(space: Any, rng: np.random.Generator) -> Callable[[np.ndarray], Any]:
    """Uniformly random actions of a Discrete or Box action space, drawn from `rng`."""
    if isinstance(space, gymnasium.spaces.Discrete):
        return lambda _: int(rng.integers(int(space.n)))
    return lambda _: rng.uniform(space.low, space.high).astype(space.dtype)
