"""Monoped-v0: the hopper learns to stay up (seed 001's MonopedEnv, gymnasium 1.x API).

| | |
|---|---|
| Actions (Discrete 6) | 0/1: haa +/- joint_increment_value, 2/3: hfe +/-, 4/5: kfe +/-, from the current joint positions, clamped to the URDF limits |
| Observation (float32 Box 8) | distance of the base from desired_pose (m), base roll, pitch, yaw (IMU, rad), foot contact force (N, 0 in the air), haa, hfe, kfe positions (rad) |
| Reward | alive_reward - (r1 + r2 + r3 + r4 + r5) (MonopedState), done_reward on a fall |
| Terminated | base height outside [min_height, max_height), or abs(roll) or abs(pitch) >= max_incl |
| Truncated | after nsteps steps |
| Step | the three joint targets are published and the sim advances running_step of sim time in lockstep |

Fixes over the tutorial: an observation_space (gymnasium's env checker failed on its absence, see
the comment under seed 001), the 5-tuple step and reset(seed=, options=), no time.sleep(running_step)
of wall time between unpause and pause (the sim advances exactly running_step), no gravity switching
during reset, and a TimeLimit that matches nsteps (the tutorial registered 50 steps).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

import numpy as np
from gymnasium import spaces

from robot_rl.backends import Backend, Readings, make_backend
from robot_rl.env_base import RobotEnv
from .joint_publisher import JointPub
from .monoped_state import MonopedState
from .params import load_default_params

REPO = Path(__file__).resolve().parents[3]
URDF = REPO / "hopper_description" / "urdf" / "monoped.urdf"
SIM_CONFIG = REPO / "config" / "hopper_sim.yaml"


class MonopedEnv(RobotEnv):
    def __init__(self, backend: str | Backend = "ros", params: Optional[Dict[str, Any]] = None,
                 seed: Optional[int] = None, ros_timeout: float = 10.0):
        """`params`: validated hopper params (default: config/hopper_qlearn.yaml).
        `backend`: "ros" (a running sim node), "direct" (in-process World seeded with `seed`) or a Backend."""
        self.params = dict(params) if params is not None else load_default_params()
        super().__init__(make_backend(backend, URDF, SIM_CONFIG, seed=seed, timeout=ros_timeout),
                         running_step=self.params["running_step"], max_episode_steps=self.params["nsteps"])
        self.monoped_state = MonopedState.from_params(self.params)
        self.joint_pub = JointPub(self.backend)
        self.action_space = spaces.Discrete(6)
        high = np.array([np.inf, math.pi, math.pi / 2, math.pi, np.inf, math.pi, math.pi, math.pi], dtype=np.float32)
        low = -high
        low[[0, 4]] = 0.0
        self.observation_space = spaces.Box(low, high, dtype=np.float32)

    def _reset_commands(self) -> None:
        self.joint_pub.set_init_pose()

    def _start_episode(self, readings: Readings) -> None:
        self.monoped_state.update(readings)

    def _apply_action(self, action: int) -> None:
        self.joint_pub.move_joints(
            self.monoped_state.get_action_to_position(action, self.monoped_state.get_joint_positions()))

    def _observe(self, readings: Readings) -> np.ndarray:
        self.monoped_state.update(readings)
        return self.monoped_state.get_observations()

    def _reward_and_termination(self, observation: np.ndarray) -> Tuple[float, bool, Dict[str, Any]]:
        reward, done = self.monoped_state.process_data()
        return reward, done, {"fell": done, "base_height": self.monoped_state.get_base_height()}
