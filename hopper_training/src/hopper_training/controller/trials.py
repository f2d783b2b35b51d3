"""Hopping trials of the controller on an in-process World (no ROS): the staged validation of docs/guide/hopping.md.

A trial spawns the monoped as its sim config says (the foot 5 cm above the ground, the leg straight),
optionally leaned by a tilt or on the vertical slider (`base_constraint: vertical`), runs
HopController every `control_period` of sim time for `duration`, and measures it from the sim's true
base pose (not the noisy odometry the controller reads): apex heights, the largest tilt, drift, the
forward speed over the last 5 s, and whether it fell as the monoped tasks define a fall (base below
0.5 m, or abs(roll) or abs(pitch) >= 1.57 rad).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from pybullet_sim.config import parse_robot_config
from pybullet_sim.readings import FrameState
from pybullet_sim.world import World

from ..robot import CONTROLLERS
from .core import HopController, HopGains, euler_sxyz, hop_input

MIN_HEIGHT = 0.5        # m: the monoped tasks' min_height
MAX_TILT = 1.57         # rad: their max_incl
SPEED_WINDOW_S = 5.0    # s: the forward speed is measured over the last this much of a trial
SETTLE_S = 1.0          # s: stage 1's apexes count from here on (the first hops settle from the spawn drop)
INITIAL_TILT = (0.02, 0.05)  # rad: the lean a free trial starts from (issue 27's evaluation perturbation)
PUSH_TIME_S = 4.0       # s: when stage 4's kick comes


@dataclass(frozen=True)
class Push:
    """A velocity kick: at `time` s the base's velocity gains `velocity` (m/s, world x, y, z)."""

    time: float
    velocity: tuple[float, float, float]


@dataclass(frozen=True)
class TrialResult:
    fell: bool
    duration: float                  # s of sim time until the fall or the end
    hops: int                        # touchdowns
    apexes: tuple[float, ...]        # m: base height at each apex of a flight
    apex_times: tuple[float, ...]    # s: when each apex was
    max_tilt: float                  # rad: the largest abs(roll) or abs(pitch)
    drift: float                     # m: horizontal distance of the base from its start
    forward_speed: float             # m/s: mean base speed along +x over the last SPEED_WINDOW_S (or the trial)
    lateral_drift: float             # m: base y at the end minus at the start


def load_sim_config(path: Path, **overrides: Any) -> dict[str, Any]:
    """A robot's sim config YAML as a dict, with top-level keys replaced (e.g. base_constraint="vertical")."""
    params = yaml.safe_load(path.read_text())
    params.update(overrides)
    return params


def make_world(urdf: Path, sim_config: Mapping[str, Any], seed: int = 0) -> World:
    return World(urdf.read_text(), parse_robot_config(sim_config, where="sim config"), seed=seed,
                 urdf_source=str(urdf))


def lean(world: World, tilt: float, direction: float) -> None:
    """Lean the base by `tilt` rad about a horizontal axis: its top moves towards `direction` (rad from +x)."""
    state = world.model_state()
    half = tilt / 2.0
    # the axis z x (cos d, sin d, 0) = (-sin d, cos d, 0): a positive turn about it tips +z towards d
    orientation = (-math.sin(direction) * math.sin(half), math.cos(direction) * math.sin(half), 0.0, math.cos(half))
    world.set_model_state(FrameState(state.position, orientation, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))


def run_trial(world: World, controller: HopController, duration: float, control_period: float = 0.001,
              push: Push | None = None) -> TrialResult:
    """Run the controller on the world from its current state for `duration` s of sim time (see the module)."""
    sensors = {s.type: s for s in world.config.sensors}
    every = max(1, round(control_period / world.time_step))
    steps = round(duration / world.time_step)
    start = world.model_state().position
    heights: list[float] = []
    xs: list[float] = []
    max_tilt, fell, pushed = 0.0, False, push is None
    step = 0
    for step in range(steps):
        state = world.model_state()
        roll, pitch, _ = euler_sxyz(state.orientation)
        max_tilt = max(max_tilt, abs(roll), abs(pitch))
        heights.append(state.position[2])
        xs.append(state.position[0])
        if state.position[2] < MIN_HEIGHT or abs(roll) >= MAX_TILT or abs(pitch) >= MAX_TILT:
            fell = True
            break
        if not pushed and push is not None and world.time >= push.time:
            velocity = tuple(v + dv for v, dv in zip(state.linear_velocity, push.velocity, strict=True))
            world.set_model_state(FrameState(state.position, state.orientation, velocity, state.angular_velocity))
            pushed = True
        if step % every == 0:
            reading = hop_input(world.read_joint_states(), world.read_sensor(sensors["imu"]),
                                world.read_sensor(sensors["p3d"]), world.read_sensor(sensors["contact"]))
            for name, target in zip(CONTROLLERS, controller.update(reading), strict=True):
                world.set_command(name, target)
        world.step()
    end = world.model_state().position
    window = min(len(xs) - 1, round(SPEED_WINDOW_S / world.time_step))
    forward_speed = (xs[-1] - xs[-1 - window]) / (window * world.time_step) if window > 0 else 0.0
    peaks = apex_indices(heights)
    return TrialResult(fell=fell, duration=len(heights) * world.time_step, hops=controller.hops,
                       apexes=tuple(heights[i] for i in peaks), apex_times=tuple(i * world.time_step for i in peaks),
                       max_tilt=max_tilt,
                       drift=math.hypot(end[0] - start[0], end[1] - start[1]), forward_speed=forward_speed,
                       lateral_drift=end[1] - start[1])


def apex_indices(heights: list[float], window: int = 100, prominence: float = 0.005) -> list[int]:
    """Where a height series has its apexes: local maxima that are the highest within +/- `window` samples
    and stand `prominence` m above the lowest point around them (one per flight)."""
    z = np.asarray(heights)
    found = []
    for i in range(1, len(z) - 1):
        around = z[max(0, i - window):i + window + 1]
        if z[i] >= z[i - 1] and z[i] > z[i + 1] and z[i] == around.max() and z[i] - around.min() >= prominence:
            found.append(i)
    return found



@dataclass(frozen=True)
class StageSettings:
    """What every stage shares: episodes, their length, the seed of their starts and noise, the robot."""

    urdf: Path
    sim_config: Path
    episodes: int = 20
    duration: float = 10.0
    seed: int = 0
    control_period: float = 0.001
    gains: HopGains = HopGains()


def stage_vertical(settings: StageSettings) -> dict[str, Any]:
    """Stage 1: the base on the vertical slider; apex heights after the first SETTLE_S (the drop from the spawn)."""
    world = make_world(settings.urdf, load_sim_config(settings.sim_config, base_constraint="vertical"), settings.seed)
    try:
        result = run_trial(world, HopController(settings.gains), settings.duration, settings.control_period)
    finally:
        world.close()
    steady = [z for z, t in zip(result.apexes, result.apex_times, strict=True) if t >= SETTLE_S]
    return {"stage": "vertical", "fell": result.fell, "hops": result.hops, "apexes": len(steady),
            "apex_mean_m": _mean(steady), "apex_sd_m": float(np.std(steady)) if steady else None,
            "apex_range_m": (max(steady) - min(steady)) if steady else None}


def stage_free(settings: StageSettings, speed: tuple[float, float] = (0.0, 0.0), push: float = 0.0) -> dict[str, Any]:
    """Stages 2-4: free 3D hopping, `episodes` trials each from a lean of 0.02-0.05 rad in a random direction
    (drawn from `seed`), commanded `speed`; with `push` > 0 a kick of that many m/s in a random horizontal
    direction at PUSH_TIME_S."""
    rng = np.random.default_rng(settings.seed)
    gains = replace(settings.gains, speed=speed)
    world = make_world(settings.urdf, load_sim_config(settings.sim_config), settings.seed)
    results = []
    try:
        for _ in range(settings.episodes):
            world.reset_simulation()
            lean(world, float(rng.uniform(*INITIAL_TILT)), float(rng.uniform(0.0, 2.0 * math.pi)))
            kick = None
            if push > 0.0:
                heading = float(rng.uniform(0.0, 2.0 * math.pi))
                kick = Push(PUSH_TIME_S, (push * math.cos(heading), push * math.sin(heading), 0.0))
            results.append(run_trial(world, HopController(gains), settings.duration, settings.control_period, kick))
    finally:
        world.close()
    upright = [not r.fell for r in results]
    return {"stage": "push" if push > 0.0 else ("forward" if any(speed) else "in_place"),
            "episodes": len(results), "speed_mps": list(speed), "push_mps": push,
            "upright_rate": sum(upright) / len(results),
            "max_tilt_rad": max(r.max_tilt for r in results), "mean_max_tilt_rad": _mean([r.max_tilt for r in results]),
            "mean_drift_m": _mean([r.drift for r in results]), "max_drift_m": max(r.drift for r in results),
            "mean_forward_speed_mps": _mean([r.forward_speed for r in results]),
            "min_forward_speed_mps": min(r.forward_speed for r in results),
            "mean_lateral_drift_m": _mean([r.lateral_drift for r in results]),
            "mean_apex_m": _mean([z for r in results for z in r.apexes]),
            "mean_hops": _mean([float(r.hops) for r in results])}


def _mean(values: list[float]) -> float | None:
    return float(np.mean(values)) if values else None
