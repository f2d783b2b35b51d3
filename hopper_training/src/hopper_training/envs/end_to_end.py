"""MonopedEndToEnd-v0: the monoped hops by a learned policy alone, every control period (issue 39, Track A).

Nothing hand-written runs in this env's step: the action is the three absolute joint targets, every
running_step (5 ms; 10 ms is a documented variant, config/end_to_end.yaml). The hopping controller
(controller/core.py) is only a teacher outside the env (hopper_training/teacher/: BC and DAgger), never part of
the step. The monoped env base (envs/base.py) gives the start, the backends (direct and ROS) and the metrics.

Action: Box(3) in [-1, 1] (action_mode targets): haa, hfe, kfe targets start_pose + action * target_range (rad),
    clamped to the URDF limits; 0 is the crouch.
Start: the crouch, foot on the ground, leaning initial_tilt (0.02-0.05 rad) towards a random heading.
Observation: Box(history x 15 + 3,) float32: `history` frames (default 4), the newest first, then the last
    action; with observe_yaw, the base's yaw as cos and sin between the frames and the action (+ 2). At reset
    every frame is the first one and the last action is 0 (the crouch). One frame:
    0 roll, 1 pitch (rad, IMU)
    2 roll rate, 3 pitch rate (rad/s, IMU, base frame)
    4-6 base linear velocity (m/s, odometry) in the heading frame: world velocity turned by -yaw, so that the
        free yaw does not change what a motion looks like
    7 base height (m, odometry)
    8-10 haa, hfe, kfe positions (rad); 11-13 their velocities (rad/s)
    14 foot contact (1 touching, 0 in the air)
Reward: the sum of the terms, each in info as reward_<term> (reward_terms below; the weights in the YAML)
    alive        alive_reward every step upright
    upright      upright_weight x exp(-tilt^2 / upright_scale), tilt the angle (rad) of the base's z axis from
                 vertical: 1 x weight upright, 0.61 x at 0.22 rad, ~0.03 x at the 0.6 rad fall
    hop          hop_weight x min(flight time, hop_cap_s), paid once per hop at its touchdown: hopping pays, a
                 single long flight no more than hop_cap_s of one
    action_rate  -action_rate_weight x ||a_t - a_(t-1)||^2: chattering targets cost
    speed        -speed_weight x (v_x - target_speed)^2, v_x the base's velocity along world +x (m/s): hopping at
                 the commanded speed (0 weight in end_to_end.yaml: in place; end_to_end_forward.yaml: 0.4 m/s)
    lateral      -lateral_weight x v_y^2, v_y the base's velocity along world +y (m/s): no drift sideways (0 weight
                 but in end_to_end_assist.yaml, where an assisted policy would otherwise run off sideways)
    fall         done_reward, alone, on the step that ends the episode by a fall (a fixed penalty: nothing
                 pays for falling far or falling late)
Terminated: base height outside [min_height, max_height), or abs(roll) or abs(pitch) >= max_incl (0.6 rad).
Truncated: after nsteps steps (2000: 10 s at 5 ms). Info and metrics: Monoped-v0's (stay_up.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from robot_rl import Readings, StepOutcome, TaskSpec, param

from ..params import MonopedParams
from ..robot import IMU_SENSOR, MONOPED, ODOMETRY_SENSOR, base_rpy, contact_force, joint_positions, joint_velocities
from ..state import monoped_state_key
from .base import MonopedBaseEnv, monoped_metrics

FRAME_SIZE = 15
YAW_SIZE = 2
ACTION_SIZE = 3


@dataclass(frozen=True, kw_only=True)
class EndToEndParams(MonopedParams):
    history: int = param(low=1, high=64, default=4, doc="frames of the observation, the newest first")
    upright_weight: float = param(low=0.0, doc="reward of a step perfectly upright (x exp(-tilt^2 / upright_scale))")
    upright_scale: float = param(low=0.0, low_open=True, doc="rad^2: the width of the upright term")
    hop_weight: float = param(low=0.0, doc="reward per second of flight, paid at touchdown")
    hop_cap_s: float = param(low=0.0, doc="s: one hop's flight pays at most this long")
    action_rate_weight: float = param(low=0.0, doc="penalty weight of ||a_t - a_(t-1)||^2")
    target_speed: float = param(low=-1.0, high=1.0, default=0.0,
                                doc="m/s along world +x to hop at: the speed term's target and the teacher's command")
    speed_weight: float = param(low=0.0, default=0.0, doc="penalty weight of (v_x - target_speed)^2, m/s world x")
    lateral_weight: float = param(low=0.0, default=0.0, doc="penalty weight of v_y^2, m/s world y")
    observe_yaw: bool = param(default=False, doc="the base's yaw (cos, sin) in the observation: the world's +x")


END_TO_END = TaskSpec(
    name="end_to_end", env_id="MonopedEndToEnd-v0", entry_point=f"{__name__}:MonopedEndToEndEnv",
    package="hopper_training", robot=MONOPED, params_type=EndToEndParams, params_namespace="/",
    state_key=monoped_state_key, results_name="end_to_end", reward_topic="/monoped/reward",
    episode_reward_topic="/monoped/episode_reward", publish_cumulated_reward=True, max_episode_steps=2000,
    metrics=monoped_metrics, headline_metric="time_upright_s", eval_horizon_s=10.0, curve_metrics=("hops",))


def tilt_angle(roll: float, pitch: float) -> float:
    """The angle (rad) between the base's z axis and the vertical, for roll and pitch (axes sxyz)."""
    return math.acos(max(-1.0, min(1.0, math.cos(roll) * math.cos(pitch))))


def reward_terms(p: EndToEndParams, tilt: float, flight_s: float | None, action: np.ndarray,
                 last_action: np.ndarray, speed_x: float = 0.0, speed_y: float = 0.0) -> dict[str, float]:
    """The terms of a step upright: `tilt` (rad from vertical), `flight_s` the flight that ended with this step's
    touchdown (None: no touchdown this step), the action and the one before, the base's speed along world +x and
    +y."""
    hop = 0.0 if flight_s is None else p.hop_weight * min(flight_s, p.hop_cap_s)
    change = np.asarray(action, np.float64) - np.asarray(last_action, np.float64)
    return {"alive": p.alive_reward, "upright": p.upright_weight * math.exp(-tilt * tilt / p.upright_scale),
            "hop": hop, "action_rate": -p.action_rate_weight * float(change @ change),
            "speed": -p.speed_weight * (speed_x - p.target_speed) ** 2, "lateral": -p.lateral_weight * speed_y ** 2}


def frame(readings: Readings) -> np.ndarray:
    """One frame of the observation (the module docstring lists its 15 values)."""
    roll, pitch, yaw = base_rpy(readings)
    rates = readings.imu(IMU_SENSOR).angular_velocity
    odometry = readings.odometry(ODOMETRY_SENSOR)
    vx, vy, vz = odometry.linear_velocity
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([roll, pitch, rates[0], rates[1], c * vx + s * vy, -s * vx + c * vy, vz, odometry.position[2],
                     *joint_positions(readings), *joint_velocities(readings),
                     1.0 if contact_force(readings) > 0.0 else 0.0], dtype=np.float32)


class MonopedEndToEndEnv(MonopedBaseEnv):
    task: ClassVar[TaskSpec[Any]] = END_TO_END
    params: EndToEndParams

    def _spaces(self) -> tuple[spaces.Discrete | spaces.Box, spaces.Box]:
        frame_high = np.full(FRAME_SIZE, np.inf, np.float32)
        frame_low = -frame_high
        frame_low[14], frame_high[14] = 0.0, 1.0
        k, yaw = self.params.history, YAW_SIZE if self.params.observe_yaw else 0
        low = np.concatenate([np.tile(frame_low, k), -np.ones(yaw + ACTION_SIZE, np.float32)])
        high = np.concatenate([np.tile(frame_high, k), np.ones(yaw + ACTION_SIZE, np.float32)])
        return self.actions.space(), spaces.Box(low, high, dtype=np.float32)

    def _start_episode(self, readings: Readings) -> None:
        super()._start_episode(readings)
        self.frames = [frame(readings)] * self.params.history
        self.frame_stamp = readings.stamp  # the sim time of the newest frame
        self.action = self.last_action = np.zeros(ACTION_SIZE, np.float32)
        self.in_contact = contact_force(readings) > 0.0
        self.lift_off = readings.stamp

    def _apply_action(self, action: Any, readings: Readings) -> None:
        self.last_action, self.action = self.action, np.asarray(action, np.float32)
        super()._apply_action(action, readings)

    def _observe(self, readings: Readings) -> np.ndarray:
        if readings.stamp != self.frame_stamp:  # a step's new readings (a step always advances sim time)
            self.frames = [frame(readings), *self.frames[:-1]]
            self.frame_stamp = readings.stamp
        if not self.params.observe_yaw:
            return np.concatenate([*self.frames, self.action]).astype(np.float32)
        yaw = base_rpy(readings)[2]
        return np.concatenate([*self.frames, (math.cos(yaw), math.sin(yaw)), self.action]).astype(np.float32)

    def _reward_and_termination(self, observation: np.ndarray, readings: Readings) -> StepOutcome:
        p = self.params
        roll, pitch, _ = base_rpy(readings)
        odometry = readings.odometry(ODOMETRY_SENSOR)
        position = odometry.position
        touching = contact_force(readings) > 0.0
        self.hop_tracker.add(readings.stamp, position, touching)
        flight_s = readings.stamp - self.lift_off if touching and not self.in_contact else None
        if self.in_contact and not touching:
            self.lift_off = readings.stamp
        self.in_contact = touching
        height_ok = p.min_height <= position[2] < p.max_height
        fell = not (height_ok and abs(roll) < p.max_incl and abs(pitch) < p.max_incl)
        info: dict[str, Any] = {"fell": fell, "base_height": position[2], "x_travelled": position[0] - self.start_x,
                                **self.hop_tracker.summary()}
        if fell:
            return {"fall": p.done_reward}, True, info
        terms = reward_terms(p, tilt_angle(roll, pitch), flight_s, self.action, self.last_action,
                             odometry.linear_velocity[0], odometry.linear_velocity[1])
        return terms, False, info
