"""Gymnasium env base shared by the robots: lockstep steps over a Backend, task code in subclasses.

A step is: the task turns the action into controller commands, the backend advances exactly
`running_step` of sim time, and the task turns the readings into observation, reward and
termination. No wall-clock sleeps and no wait-until-the-robot-gets-there loops: a step always lasts
running_step of sim time. `reset(seed=...)` also restarts sim time and the sensor noise
(reset_simulation), so a seeded reset makes the episode reproducible; an unseeded reset uses
reset_world, as openai_ros does for these robots. A robot spawned above the ground can be given
`settle_time` of sim time to land (with its reset commands) before the first observation.
"""
from __future__ import annotations

import abc
from typing import Any, Dict, Optional, Tuple

import gymnasium
import numpy as np

from .backends import Backend, Readings


class RobotEnv(gymnasium.Env, abc.ABC):
    """Subclasses set a Discrete action_space and an observation_space, and implement the task hooks."""

    metadata = {"render_modes": []}

    def __init__(self, backend: Backend, running_step: float, max_episode_steps: int, settle_time: float = 0.0):
        if running_step < backend.time_step:
            raise ValueError(f"running_step {running_step} s is shorter than one physics step ({backend.time_step} s)")
        if max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}")
        self.backend = backend
        self.running_step = running_step
        self.physics_steps = round(running_step / backend.time_step)
        self.max_episode_steps = max_episode_steps
        self.settle_steps = round(settle_time / backend.time_step)
        self.elapsed_steps = 0
        self.readings: Optional[Readings] = None

    # -- task hooks -----------------------------------------------------------------------------
    @abc.abstractmethod
    def _reset_commands(self) -> None:
        """Command the controllers' start values (before the robot settles)."""

    @abc.abstractmethod
    def _start_episode(self, readings: Readings) -> None:
        """Reset the task's own state (start position...) from the first readings of the episode."""

    @abc.abstractmethod
    def _apply_action(self, action: int) -> None:
        """Turn the action into controller commands with self.backend.set_command."""

    @abc.abstractmethod
    def _observe(self, readings: Readings) -> np.ndarray:
        """The observation (inside observation_space) from the readings."""

    @abc.abstractmethod
    def _reward_and_termination(self, observation: np.ndarray) -> Tuple[float, bool, Dict[str, Any]]:
        """(reward, terminated, info) for the step that produced `observation`."""

    # -- gymnasium API --------------------------------------------------------------------------
    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        self.readings = self.backend.reset(restart_time=seed is not None)
        self.elapsed_steps = 0
        self._reset_commands()
        if self.settle_steps:
            self.readings = self.backend.step(self.settle_steps)
        self._start_episode(self.readings)
        return self._observe(self.readings), {"sim_time": self.readings.stamp}

    def step(self, action):
        if self.readings is None:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        # A direct range check: Discrete.contains costs as much as a tenth of a lockstep exchange.
        if not (isinstance(action, (int, np.integer)) and 0 <= action < self.action_space.n):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        self._apply_action(int(action))
        self.readings = self.backend.step(self.physics_steps)
        self.elapsed_steps += 1
        observation = self._observe(self.readings)
        reward, terminated, info = self._reward_and_termination(observation)
        truncated = not terminated and self.elapsed_steps >= self.max_episode_steps
        info["sim_time"] = self.readings.stamp
        return observation, float(reward), terminated, truncated, info

    def close(self):
        self.backend.close()
