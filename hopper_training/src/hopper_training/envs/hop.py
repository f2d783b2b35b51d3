"""MonopedHop-v0: the monoped learns to hop forward along world +x while staying up (our own task).

The tutorial promised to make the monoped "learn to hop"; its code only taught it to stay up. This
task keeps Monoped-v0's robot, actions, observation and termination, and adds a reward for forward
progress, as Gymnasium's hopper_v5 does (forward_reward_weight * x velocity + a healthy reward), with
the velocity counted up to target_speed, so that a dive (faster than a hop) pays no more than hopping.

Actions, observation, termination, truncation, info and arguments: as Monoped-v0 (stay_up.py),
    with HopParams (default config/hop.yaml).
Reward: the sum of the terms, each in info as reward_<term>
    Monoped-v0's terms (alive, joint_position, joint_effort, contact_force, orientation, distance), with
        this task's weights (its YAML sets weight_r5 to 0: the start point no longer matters)
    forward  forward_reward_weight * min((x - previous x) / running_step, target_speed): the base's
             velocity along +x, up to target_speed (backwards counts in full)
    fall     done_reward, alone, on the step that ends the episode by a fall
Metrics: Monoped-v0's; x_distance (m along +x at the end of the episode) is the headline.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_rl import Readings, StepOutcome, TaskSpec, param

from ..params import MonopedParams
from ..robot import MONOPED, ODOMETRY_SENSOR
from ..state import monoped_state_key
from .base import monoped_metrics
from .stay_up import MonopedEnv


@dataclass(frozen=True, kw_only=True)
class HopParams(MonopedParams):
    forward_reward_weight: float = param(low=0.0, doc="reward per m/s of the base along +x")
    target_speed: float = param(low=0.0, low_open=True, default=math.inf,
                                doc="m/s: the forward reward counts the velocity along +x up to this")


HOP = TaskSpec(
    name="hop", env_id="MonopedHop-v0", entry_point=f"{__name__}:MonopedHopEnv", package="hopper_training",
    robot=MONOPED, params_type=HopParams, params_namespace="/", state_key=monoped_state_key,
    results_name="hop", reward_topic="/monoped/reward", episode_reward_topic="/monoped/episode_reward",
    publish_cumulated_reward=True, max_episode_steps=500, metrics=monoped_metrics, headline_metric="x_distance",
    eval_horizon_s=10.0, curve_metrics=("forward_speed", "hops"))


class MonopedHopEnv(MonopedEnv):
    task = HOP
    params: HopParams

    def _start_episode(self, readings: Readings) -> None:
        super()._start_episode(readings)
        self._previous_x = self.start_x

    def _reward_and_termination(self, observation: np.ndarray, readings: Readings) -> StepOutcome:
        terms, fell, info = super()._reward_and_termination(observation, readings)
        x = readings.odometry(ODOMETRY_SENSOR).position[0]
        if not fell:
            velocity = (x - self._previous_x) / self.running_step
            terms["forward"] = self.params.forward_reward_weight * min(velocity, self.params.target_speed)
        self._previous_x = x
        return terms, fell, info
