"""MonopedResidualInPlace-v0: the monoped hops in place, a deep agent's action added to the hopping controller's
joint targets (issue 27, "learned hopping, deep", the residual mode). MonopedResidualForward-v0
(residual_forward.py) is this task commanded forward.

One env step is one hop, lift-off to lift-off, as MonopedHopInPlace-v0's (hop_cycle.py: HopCycleEnv): the
hand-written controller (controller/core.py) runs the hop cycle every running_step below it. Its foot placement law
is switched off (neutral_point and speed_feedback false in the YAMLs): alone it sets the hips so that the foot
lands under the centre of mass, and the robot runs away and falls (evaluate.py --policy do_nothing).
Learned (the action, once per hop): residual_range x action (rad) added to the haa and hfe targets that the
    controller's flight inverse kinematics solve for (HopController.hip_offset), held from this lift-off to the
    next. It is where the foot lands, in the body's frame: haa sideways, hfe fore and aft.
Hand-written: everything else of the hop cycle (phase machine, thrust, stance attitude, swing), as on
    hop_in_place (docs/guide/hop_in_place.md).

Action: Box(2,) float32 in [-1, 1]: the haa and hfe residuals, in units of residual_range. Zero is the
    controller alone (with its placement law off).
Observation: Box(10,) float32 at the decision point, in the heading frame (world axes turned by the base's yaw:
    forward, left), where the hips act
    0, 1  the base's horizontal velocity (m/s; the mean of the odometry's last 5 readings, as hop_in_place's)
    2, 3  the velocity error: 0, 1 minus the commanded velocity (target_speed along world +x)
    4     roll, 5 pitch (rad, IMU)
    6     roll rate, 7 pitch rate (rad/s, IMU)
    8     base height (m)
    9     the hop's duration (s of sim time since the last decision point)
Reward: the sum of the terms, each in info as reward_<term>
    alive  alive_reward per second of sim time the hop lasted (alive_reward x duration)
    speed  -speed_weight x the magnitude of the velocity error (world, m/s) at the decision point
    fall   done_reward, alone, on the step that ends the episode by a fall
Terminated, truncated, info and metrics: MonopedHopInPlace-v0's (hop_in_place.py); info adds residual (rad, haa and
    hfe). MonopedResidualForward-v0's headline metric is forward_speed (m/s along +x over the last 5 s).
The two tasks differ only in their YAML: target_speed 0 (residual_in_place) or 0.4 m/s (residual_forward).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from gymnasium import spaces

from robot_rl import Readings, StepOutcome, TaskSpec, param

from ..controller.core import HopGains
from ..robot import IMU_SENSOR, MONOPED, ODOMETRY_SENSOR, base_rpy
from ..state import monoped_state_key
from .hop_cycle import HopCycleEnv, HopCycleParams, hop_cycle_metrics


@dataclass(frozen=True, kw_only=True)
class HopResidualParams(HopCycleParams):
    residual_range: float = param(low=0.0, low_open=True, high=0.5,
                                  doc="rad: an action of +/-1 adds this to the flight's haa or hfe target")
    target_speed: float = param(low=-1.0, high=1.0, doc="m/s along world +x: the commanded velocity")


def residual_task(name: str, env_id: str, entry_point: str, headline: str) -> TaskSpec[HopResidualParams]:
    """The spec of a residual task (this one and residual_forward.py's): they differ in name and headline metric."""
    return TaskSpec(
        name=name, env_id=env_id, entry_point=entry_point, package="hopper_training", robot=MONOPED,
        params_type=HopResidualParams, params_namespace="/", state_key=monoped_state_key,
        results_name=name, reward_topic="/monoped/reward", episode_reward_topic="/monoped/episode_reward",
        publish_cumulated_reward=True, max_episode_steps=5000, metrics=hop_cycle_metrics, headline_metric=headline,
        eval_horizon_s=10.0, curve_metrics=("hops", "drift", "forward_speed"))


RESIDUAL_IN_PLACE = residual_task("residual_in_place", "MonopedResidualInPlace-v0",
                                  f"{__name__}:MonopedResidualInPlaceEnv", "time_upright_s")


class MonopedResidualInPlaceEnv(HopCycleEnv):
    task = RESIDUAL_IN_PLACE
    params: HopResidualParams

    def _controller_gains(self) -> HopGains:
        return replace(super()._controller_gains(), speed=(self.params.target_speed, 0.0))

    def _spaces(self) -> tuple[spaces.Discrete | spaces.Box, spaces.Box]:
        high = np.full(10, np.inf, dtype=np.float32)
        high[4:6] = (math.pi, math.pi / 2)
        low = -high
        low[8:10] = (-np.inf, 0.0)
        return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32), spaces.Box(low, high, dtype=np.float32)

    def _start_episode(self, readings: Readings) -> None:
        super()._start_episode(readings)
        self.residual = (0.0, 0.0)

    def _apply_action(self, action: Any, readings: Readings) -> None:
        haa, hfe = (float(a) * self.params.residual_range for a in np.asarray(action, dtype=np.float64))
        self.controller.hip_offset = [haa, hfe]
        self.residual = (haa, hfe)

    def _speed_error(self) -> tuple[float, float]:
        """The velocity minus the commanded one (m/s, world x and y)."""
        vx, vy, _, _ = self._velocity_frame()
        return vx - self.params.target_speed, vy

    def _observe(self, readings: Readings) -> np.ndarray:
        vx, vy, _, _ = self._velocity_frame()
        ex, ey = self._speed_error()
        roll, pitch, yaw = base_rpy(readings)
        c, s = math.cos(yaw), math.sin(yaw)

        def heading(x: float, y: float) -> tuple[float, float]:
            return c * x + s * y, -s * x + c * y
        rates = readings.imu(IMU_SENSOR).angular_velocity
        height = readings.odometry(ODOMETRY_SENSOR).position[2]
        return np.array([*heading(vx, vy), *heading(ex, ey), roll, pitch, rates[0], rates[1], height, self.hop_time],
                        dtype=np.float32)

    def _reward_and_termination(self, observation: np.ndarray, readings: Readings) -> StepOutcome:
        p = self.params
        info = {**self._hop_info(readings), "residual": self.residual}
        if self.fell:
            return {"fall": p.done_reward}, True, info
        return {"alive": p.alive_reward * self.hop_time, "speed": -p.speed_weight * math.hypot(*self._speed_error())
                }, False, info
