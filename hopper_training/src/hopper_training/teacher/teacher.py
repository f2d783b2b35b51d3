"""The teacher: the hopping controller (controller/core.py) shadow-run on whatever states the env visits.

Every step, whoever acts (the teacher itself, or the student), the controller reads the env's latest readings
and updates its phase machine, so that its label for a state is what it would command there after having lived
through the same trajectory, at the student's control period, with the gains for that period (FIVE_MS_GAIN_CHANGES),
commanded the task's target_speed. Its action is the label the student learns.
"""
from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np

from ..controller.policy import five_ms_controller


class Teacher:
    """The controller's action for the env's current state; reset() at each episode's start, then label() once
    per step, before the step (the controller's phase machine follows the trajectory)."""

    def __init__(self, env: Any):
        self.controller = five_ms_controller(env, env.unwrapped.params.target_speed)

    def gains(self) -> dict[str, Any]:
        """The controller's HopGains as JSON holds them (a run's checkpoint records its teacher)."""
        return json.loads(json.dumps(dataclasses.asdict(self.controller.controller.gains)))

    def reset(self) -> None:
        self.controller.reset()

    def label(self, observation: np.ndarray) -> np.ndarray:
        """The action (Box(3), in [-1, 1]) the controller commands for the env's latest readings."""
        return self.controller(observation)
