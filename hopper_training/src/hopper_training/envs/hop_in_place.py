"""MonopedHopInPlace-v0: the monoped hops in place, one decision per hop (issue 27, "learned hopping, tabular").

Its former env id, MonopedHopLevel-v0, is registered too, as an alias.

Per-step actions every 20 ms cannot hop (the controller needs a command every 1 ms,
docs/research/2026-11-25-hop-stages.md), so one env step here is one hop: from a lift-off to the next. In
between, the hand-written hop cycle of the controller (controller/core.py) runs every control period
(running_step, 1 ms) through the backend, in lockstep as every task's step (hop_cycle.py: HopCycleEnv).
Hand-written (controller/core.py): the phase machine, the landing crouch and the thrust, the stance attitude (hip
    torques through the centre of mass, PD on the tilt), the flight swing and the leg's inverse kinematics.
Learned (the action, once per hop): where the foot lands, as an offset along the velocity. The controller's
    own placement law is switched off: its speed feedback k_v (v - v_d) and per-hop sum b always
    (HopGains.speed_feedback), and with neutral_point false (the YAML's) Raibert's neutral point v T_s / 2
    too, so that the offset is the whole placement from under the centre of mass. With thrust_levels > 1
    the knee's thrust target is learned too.

Decision point: lift-off (the controller's stance -> FLIGHT, 5 ms after the foot leaves the ground). The
horizontal velocity is then fixed until touchdown (a ballistic flight), and it is the velocity that the
foot placement of this flight must answer; the whole flight is left for the swing. The velocity is the
mean of the odometry's last VELOCITY_WINDOW readings (5 ms, all in the air): the odometry's noise (0.01 m/s)
drops by half, which matters for the direction at in-place speeds (a few cm/s).
Actions: Discrete(offset_levels x thrust_levels); action a = offset index a // thrust_levels, thrust index
    a % thrust_levels.
    offset  the foot is placed offset_min + i (offset_max - offset_min) / (offset_levels - 1) m ahead of the
            centre of mass (of the neutral point with neutral_point true) along the direction of the
            horizontal velocity at the decision point (behind when negative; along +x when the speed is
            below 1 mm/s), for this flight
    thrust  the knee's thrust target in the next stance: thrust_min + j (thrust_max - thrust_min) /
            (thrust_levels - 1) rad (0: straight)
    `do_nothing_action` (offset 0, thrust default_thrust) adds nothing to the hand-written part: the foot
    lands under the centre of mass (at the neutral point with neutral_point true).
Observation: Box(8,) float32, at the decision point
    0, 1  vx, vy: the base's horizontal velocity (m/s, world, odometry; the mean of the last 5 readings)
    2     speed: its magnitude (m/s)
    3     lean along the velocity: the horizontal component of the base's z axis along the velocity's
          direction (sin of the tilt towards where the robot moves; along +x when the speed is below 1 mm/s)
    4     roll, 5 pitch (rad, IMU)
    6     base height (m)
    7     the hop's duration (s of sim time since the last decision point)
State key (state_key hop): speed in bins (edges SPEED_EDGES) x the sign of the lean along the velocity:
    8 x 2 = 16 keys (HopInPlaceStateKey); state_key speed: the speed alone in 5 coarser bins (SpeedStateKey).
Reward: the sum of the terms, each in info as reward_<term>
    alive  alive_reward per second of sim time the hop lasted (alive_reward x duration)
    speed  -speed_weight x the speed at the decision point (hop in place: moving costs)
    fall   done_reward, alone, on the step that ends the episode by a fall
Terminated: Monoped-v0's fall rule (base height outside [min_height, max_height), abs(roll) or abs(pitch) >=
    max_incl), checked every control period.
Truncated: by the env itself, when the episode's sim time reaches nsteps x running_step (10000 x 1 ms =
    10 s; robot_rl.task.make_env sets nsteps to the TimeLimit's, so evaluate.py's --horizon-s works), so that
    an episode lasts as many sim seconds as every monoped task's. A step with no lift-off within max_hop_s also ends.
Info: Monoped-v0's (fell, base_height, x_travelled, hops, apex_height, forward_speed, lateral_drift), the
    reward terms, sim_time, episode_time (sim s since the reset: training and evaluation take the episode's
    duration from it, since steps differ in length), hop_time (s), offset (m), thrust_knee (rad).
Metrics: Monoped-v0's (time_upright_s from episode_time), and drift (m: the base's horizontal distance
    from where the episode started).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from gymnasium import spaces

from robot_rl import Discretiser, ParamError, Readings, StateKey, StepOutcome, TaskSpec, param

from ..robot import MONOPED, ODOMETRY_SENSOR, base_rpy
from .hop_cycle import HopCycleEnv, HopCycleParams, hop_cycle_metrics

SPEED_EDGES = [0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5]  # m/s
LEAN_EDGES = [0.0]                          # the sign of the lean towards the velocity
COARSE_SPEED_EDGES = [0.1, 0.25, 0.5, 0.8]  # m/s: state_key speed's bins


@dataclass(frozen=True, kw_only=True)
class HopInPlaceParams(HopCycleParams):
    state_key: str = param(choices=("hop", "speed"), default="hop",
                           doc="the Q-learning state key: hop (HopInPlaceStateKey) or speed (SpeedStateKey)")
    offset_min: float = param(low=-0.2, high=0.2, doc="m: the foot placement offset of offset index 0")
    offset_max: float = param(low=-0.2, high=0.2, doc="m: that of the last offset index")
    offset_levels: int = param(low=1, high=15, doc="offsets to choose from")
    thrust_min: float = param(low=-0.5, high=0.0, doc="rad: the knee's thrust target of thrust index 0")
    thrust_max: float = param(low=-0.5, high=0.0, doc="rad: that of the last thrust index")
    thrust_levels: int = param(low=1, high=5, doc="thrusts to choose from")
    default_thrust: float = param(low=-0.5, high=0.0, doc="rad: the do-nothing action's thrust (a level)")

    def check(self, source: str) -> None:
        super().check(source)
        if self.offset_levels > 1 and not self.offset_min < self.offset_max:
            raise ParamError(f"{source}: parameter 'offset_min' ({self.offset_min}) must be below 'offset_max'")
        if self.thrust_levels > 1 and not self.thrust_min < self.thrust_max:
            raise ParamError(f"{source}: parameter 'thrust_min' ({self.thrust_min}) must be below 'thrust_max'")
        if not any(math.isclose(t, self.default_thrust) for t in thrust_knees(self)):
            raise ParamError(f"{source}: parameter 'default_thrust' ({self.default_thrust}) is not one of the "
                             f"thrust levels {thrust_knees(self)}")
        if not any(math.isclose(o, 0.0, abs_tol=1e-9) for o in offsets(self)):
            raise ParamError(f"{source}: no offset level is 0 (the do-nothing action): {offsets(self)}")


def _levels(low: float, high: float, n: int) -> list[float]:
    return [low] if n == 1 else [float(v) for v in np.linspace(low, high, n)]


def offsets(params: HopInPlaceParams) -> list[float]:
    """The foot placement offsets (m along the velocity), by offset index."""
    return _levels(params.offset_min, params.offset_max, params.offset_levels)


def thrust_knees(params: HopInPlaceParams) -> list[float]:
    """The knee's thrust targets (rad), by thrust index."""
    return _levels(params.thrust_min, params.thrust_max, params.thrust_levels)


def action_meaning(params: HopInPlaceParams, action: int) -> tuple[float, float]:
    """(offset m, thrust knee rad) of an action."""
    offset, thrust = divmod(int(action), params.thrust_levels)
    return offsets(params)[offset], thrust_knees(params)[thrust]


def do_nothing_action(params: HopInPlaceParams) -> int:
    """The action of offset 0 and the default thrust: the hand-written part alone."""
    offset = next(i for i, o in enumerate(offsets(params)) if math.isclose(o, 0.0, abs_tol=1e-9))
    thrust = next(i for i, t in enumerate(thrust_knees(params)) if math.isclose(t, params.default_thrust))
    return offset * params.thrust_levels + thrust


class HopInPlaceStateKey:
    """Speed in bins (SPEED_EDGES) and the sign of the lean along the velocity (LEAN_EDGES): 8 x 2 keys."""

    def __init__(self, params: HopInPlaceParams):
        self.discretiser = Discretiser.from_edges([SPEED_EDGES, LEAN_EDGES])

    def key(self, observation: np.ndarray) -> str:
        return self.discretiser.key([float(observation[2]), float(observation[3])])

    def to_dict(self) -> dict[str, Any]:  # the format keeps its old name: checkpoints (the shipped one) record it
        return {"format": "hopper_training.hop_level_state_key/2", "discretiser": self.discretiser.to_dict()}


class SpeedStateKey:
    """The speed alone, in coarse bins (COARSE_SPEED_EDGES): 5 keys, so that each (state, action) pair is sampled
    more often than under HopInPlaceStateKey's 16 keys when pushes make the returns noisy."""

    def __init__(self, params: HopInPlaceParams):
        self.discretiser = Discretiser.from_edges([COARSE_SPEED_EDGES])

    def key(self, observation: np.ndarray) -> str:
        return self.discretiser.key([float(observation[2])])

    def to_dict(self) -> dict[str, Any]:
        return {"format": "hopper_training.hop_in_place_speed_key/1", "discretiser": self.discretiser.to_dict()}


def hop_in_place_state_key(params: HopInPlaceParams) -> StateKey:
    return SpeedStateKey(params) if params.state_key == "speed" else HopInPlaceStateKey(params)


HOP_IN_PLACE = TaskSpec(
    name="hop_in_place", env_id="MonopedHopInPlace-v0", entry_point=f"{__name__}:MonopedHopInPlaceEnv",
    package="hopper_training", robot=MONOPED, params_type=HopInPlaceParams, params_namespace="/",
    state_key=hop_in_place_state_key, results_name="hop_in_place", reward_topic="/monoped/reward",
    episode_reward_topic="/monoped/episode_reward", publish_cumulated_reward=True, max_episode_steps=10000,
    metrics=hop_cycle_metrics, headline_metric="time_upright_s", eval_horizon_s=10.0, curve_metrics=("hops", "drift"),
    former_env_ids=("MonopedHopLevel-v0",))


class MonopedHopInPlaceEnv(HopCycleEnv):
    task = HOP_IN_PLACE
    params: HopInPlaceParams

    def _spaces(self) -> tuple[spaces.Discrete | spaces.Box, spaces.Box]:
        p = self.params
        high = np.array([np.inf, np.inf, np.inf, 1.0, math.pi, math.pi / 2, np.inf, np.inf], dtype=np.float32)
        low = np.array([-np.inf, -np.inf, 0.0, -1.0, -math.pi, -math.pi / 2, -np.inf, 0.0], dtype=np.float32)
        return spaces.Discrete(p.offset_levels * p.thrust_levels), spaces.Box(low, high, dtype=np.float32)

    def _start_episode(self, readings: Readings) -> None:
        super()._start_episode(readings)
        self.offset, self.thrust = 0.0, self.params.default_thrust

    def _apply_action(self, action: Any, readings: Readings) -> None:
        offset, thrust = action_meaning(self.params, action)
        _, _, _, (ux, uy) = self._velocity_frame()
        controller = self.controller
        controller.placement_offset = [offset * ux, offset * uy]
        controller.gains = replace(controller.gains, thrust_knee=thrust)
        if controller.hops > 0:  # from the first touchdown on, the controller's thrust is this hop's
            controller.thrust_knee = thrust
        self.offset, self.thrust = offset, thrust

    def _observe(self, readings: Readings) -> np.ndarray:
        vx, vy, speed, (ux, uy) = self._velocity_frame()
        roll, pitch, yaw = base_rpy(readings)
        cr, sr, sp = math.cos(roll), math.sin(roll), math.sin(pitch)
        lean_x, lean_y = sp * cr, -sr  # the base's z axis turned by roll, then pitch (sxyz); yaw below
        world_lean = (math.cos(yaw) * lean_x - math.sin(yaw) * lean_y, math.sin(yaw) * lean_x + math.cos(yaw) * lean_y)
        lean = world_lean[0] * ux + world_lean[1] * uy
        height = readings.odometry(ODOMETRY_SENSOR).position[2]
        return np.array([vx, vy, speed, min(max(lean, -1.0), 1.0), roll, pitch, height, self.hop_time],
                        dtype=np.float32)

    def _reward_and_termination(self, observation: np.ndarray, readings: Readings) -> StepOutcome:
        p = self.params
        info = {**self._hop_info(readings), "offset": self.offset, "thrust_knee": self.thrust}
        if self.fell:
            return {"fall": p.done_reward}, True, info
        return {"alive": p.alive_reward * self.hop_time, "speed": -p.speed_weight * float(observation[2])}, False, info
