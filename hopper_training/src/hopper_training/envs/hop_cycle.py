"""The base of the monoped's tasks whose step is one hop (hop_in_place, residual_in_place, residual_forward): the
hand-written controller runs the hop cycle every running_step, lift-off to lift-off, with their shared params,
info and metrics."""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import gymnasium
import numpy as np

from robot_rl import Episode, MetricValue, Readings, param

from ..controller.core import HopController, HopGains, Phase, hop_input
from ..params import MonopedParams
from ..robot import CONTACT_SENSOR, CONTROLLERS, IMU_SENSOR, ODOMETRY_SENSOR, base_rpy, contact_force
from .base import MonopedBaseEnv, monoped_metrics

MAX_CONTROL_PERIOD_S = 0.005               # s: the longest running_step the hop cycle's controller works at
MIN_SPEED = 1e-3                            # m/s: below this the velocity has no direction
VELOCITY_WINDOW = 5                         # readings: the velocity at a decision point is their mean
STANCE_PHASES = (Phase.LOADING, Phase.COMPRESSION, Phase.THRUST, Phase.UNLOADING)


@dataclass(frozen=True, kw_only=True)
class HopCycleParams(MonopedParams):
    """The params of the tasks whose step is one hop of the controller's cycle (hop_in_place, the residual tasks)."""

    running_step: float = param(low=0.0, low_open=True, high=MAX_CONTROL_PERIOD_S,
                                doc="s: the controller's control period (at most 5 ms: it keeps the robot up to "
                                    "5 ms and falls from 10 ms, docs/research/2026-11-25-hop-stages.md)")
    speed_weight: float = param(low=0.0, doc="reward per hop: minus this x the speed error (m/s) at the decision point")
    max_hop_s: float = param(low=0.1, high=5.0, doc="s: a step ends after this without a lift-off")
    neutral_point: bool = param(default=True, doc="the controller's neutral point v T_s / 2 (false: the agent's too)")
    speed_feedback: bool = param(default=False, doc="the controller's own k_v (v - v_d) and b: true only for "
                                                    "evaluate.py --policy controller")


def hop_cycle_metrics(episode: Episode) -> dict[str, MetricValue]:
    """Monoped-v0's metrics (time_upright_s: the episode's sim time, from info's episode_time), plus the
    horizontal drift (m)."""
    metrics = monoped_metrics(episode)
    metrics["drift"] = float(episode.info.get("drift", 0.0))
    return metrics


class HopCycleEnv(MonopedBaseEnv):
    """The monoped's tasks whose step is one hop: the controller runs the hop cycle every running_step from a
    lift-off to the next (a fall or the horizon); subclasses give the spaces, the action, the observation and
    the reward."""

    multi_period_steps = True  # a step is a hop of many control periods: period_hooks after each
    params: HopCycleParams

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.controller = HopController(self._controller_gains())

    def _controller_gains(self) -> HopGains:
        return replace(HopGains(), speed_feedback=self.params.speed_feedback, neutral_point=self.params.neutral_point)

    @property
    def start_targets(self) -> list[float]:
        pose = self.params.start_pose
        return [pose.haa, pose.hfe, pose.kfe]

    def _start_episode(self, readings: Readings) -> None:
        super()._start_episode(readings)
        self.controller.reset()
        self.episode_start = readings.stamp
        self.decision_time = readings.stamp
        self.start_xy = readings.odometry(ODOMETRY_SENSOR).position[:2]
        self.hop_time = 0.0
        self.fell = False
        self.velocities: deque[tuple[float, float]] = deque(maxlen=VELOCITY_WINDOW)
        velocity = readings.odometry(ODOMETRY_SENSOR).linear_velocity
        self.velocities.append((velocity[0], velocity[1]))

    @property
    def horizon_s(self) -> float:
        """The episode's sim time: nsteps x running_step (robot_rl.task.make_env gives the env its TimeLimit's
        nsteps)."""
        return self.params.nsteps * self.running_step

    def _velocity_frame(self) -> tuple[float, float, float, tuple[float, float]]:
        """(vx, vy, speed, unit direction of the velocity: +x below MIN_SPEED), from the last readings' mean."""
        vx, vy = (sum(v[i] for v in self.velocities) / len(self.velocities) for i in (0, 1))
        speed = math.hypot(vx, vy)
        return vx, vy, speed, ((vx / speed, vy / speed) if speed >= MIN_SPEED else (1.0, 0.0))

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One hop: the controller every running_step until the next lift-off, a fall or the horizon."""
        self._check_open()
        if self.readings is None:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        if not self.action_space.contains(action):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        self._apply_action(action, self.readings)
        self.readings = readings = self._advance()
        observation = self._observe(readings)
        terms, terminated, info = self._reward_and_termination(observation, readings)
        for name, value in terms.items():
            info[f"reward_{name}"] = value
        info["sim_time"] = readings.stamp
        truncated = not terminated and info["episode_time"] >= self.horizon_s - 1e-9
        if self.render_mode == "human":
            self.render()
        return observation, float(sum(terms.values())), terminated, truncated, info

    def _advance(self) -> Readings:
        """Run the hop cycle from the last readings to the next decision point; the last readings."""
        readings = self.readings
        assert readings is not None
        started = readings.stamp
        controller, p = self.controller, self.params
        self.fell = False
        while True:
            before = controller.phase
            targets = controller.update(hop_input(readings.joints, readings.imu(IMU_SENSOR),
                                                  readings.odometry(ODOMETRY_SENSOR), readings.contact(CONTACT_SENSOR)))
            for name, target in zip(CONTROLLERS, targets):
                self.backend.set_command(name, target)
            self.targets = list(targets)
            self.readings = readings = self._run_period()  # the pushes due first (params' push_speed)
            for hook in self.period_hooks:
                hook()
            odometry = readings.odometry(ODOMETRY_SENSOR)
            position = odometry.position
            self.velocities.append((odometry.linear_velocity[0], odometry.linear_velocity[1]))
            self.hop_tracker.add(readings.stamp, position, contact_force(readings) > 0.0)
            roll, pitch, _ = base_rpy(readings)
            if not (p.min_height <= position[2] < p.max_height and abs(roll) < p.max_incl and abs(pitch) < p.max_incl):
                self.fell = True
                break
            lift_off = before in STANCE_PHASES and controller.phase is Phase.FLIGHT
            if (lift_off or readings.stamp - self.episode_start >= self.horizon_s - 1e-9
                    or readings.stamp - started >= p.max_hop_s - 1e-9):
                break
        self.hop_time = readings.stamp - started
        return readings

    def _hop_info(self, readings: Readings) -> dict[str, Any]:
        """The info of every hop-level step (the module docstring's Info)."""
        position = readings.odometry(ODOMETRY_SENSOR).position
        return {"fell": self.fell, "base_height": position[2], "x_travelled": position[0] - self.start_x,
                **self.hop_tracker.summary(), "episode_time": readings.stamp - self.episode_start,
                "hop_time": self.hop_time, "drift": math.dist(position[:2], self.start_xy)}


def controller_params(params: HopCycleParams) -> HopCycleParams:
    """The hand-written controller on these tasks: its neutral point and speed feedback on (the do-nothing action,
    or no residual, then adds nothing to them)."""
    return params.with_changes("--policy controller", neutral_point=True, speed_feedback=True)
