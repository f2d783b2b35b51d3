"""The hopping controller as a policy of the monoped's env: `evaluate.py --policy controller`.

The env runs in action_mode targets (Box(3): start_pose + action * target_range) with a running_step of
CONTROL_PERIOD, since the controller needs a command every 1-5 ms of sim time
(docs/research/2026-11-25-hop-stages.md: at 20 ms, the env's default, it falls). Each step it reads the env's latest
readings (not the observation: it needs the odometry's velocity), runs HopController and turns its three targets
into the action.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from robot_rl import TaskSpec

from ..robot import CONTACT_SENSOR, IMU_SENSOR, ODOMETRY_SENSOR
from .core import HopController, HopGains, hop_input

CONTROL_PERIOD = 0.001  # s: the env's running_step under the controller
FIVE_MS_GAIN_CHANGES = {"placement_kv": 0.1}
"""HopGains changed at a 5 ms control period (end_to_end's: the teacher, and --policy controller there). Raibert's
speed gain of 0.2 s over-corrects a push at 5 ms: with 0.3 m/s pushes it stays up in 14 of 40 episodes (evaluation
seed 2000), 40 of 40 with 0.1 s; without pushes both hop 20 of 20 (docs/research/2026-11-27-teacher-pushes.md).
Changes, not a HopGains: nothing of the controller is built where it is only imported (test_demo.py's refusal)."""


class ControllerPolicy:
    """observation -> action of an env in action_mode targets; reset() at each episode's start."""

    def __init__(self, env: Any, speed: float = 0.0, gain_changes: Mapping[str, Any] | None = None):
        self.env = env.unwrapped
        params = self.env.params
        if params.action_mode != "targets":
            raise ValueError(f"the controller policy needs action_mode targets, the env has {params.action_mode!r}")
        self.start = np.array([params.start_pose.haa, params.start_pose.hfe, params.start_pose.kfe])
        self.target_range = params.target_range
        self.controller = HopController(replace(HopGains(), speed=(speed, 0.0), **(gain_changes or {})))

    def reset(self) -> None:
        self.controller.reset()

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        readings = self.env.readings
        targets = self.controller.update(hop_input(readings.joints, readings.imu(IMU_SENSOR),
                                                   readings.odometry(ODOMETRY_SENSOR),
                                                   readings.contact(CONTACT_SENSOR)))
        action = (np.array(targets) - self.start) / self.target_range
        return np.clip(action, -1.0, 1.0).astype(np.float32)


def five_ms_controller(env: Any, speed: float) -> ControllerPolicy:
    """The controller at end_to_end's 5 ms period (FIVE_MS_GAIN_CHANGES): its teacher, and --policy controller there."""
    return ControllerPolicy(env, speed, gain_changes=FIVE_MS_GAIN_CHANGES)


def controller_params(task: TaskSpec[Any], params: Any) -> Any:
    """The task's params as the controller needs them: action_mode targets, running_step CONTROL_PERIOD."""
    return params.with_changes("--policy controller", action_mode="targets", running_step=CONTROL_PERIOD)
