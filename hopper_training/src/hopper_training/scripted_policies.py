"""The hand-written policies evaluate.py offers on the monoped's tasks (--policy controller, do_nothing,
placement_by_speed, random)."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from robot_rl import ConstantAction, ScriptedPolicy, TaskSpec, random_actions

from .controller.policy import ControllerPolicy, five_ms_controller
from .controller.policy import controller_params as step_controller_params
from .envs.end_to_end import END_TO_END
from .envs.hop_cycle import controller_params as hop_cycle_controller_params
from .envs.hop_in_place import HOP_IN_PLACE, HopInPlaceParams, do_nothing_action, offsets
from .envs.residual_forward import RESIDUAL_FORWARD
from .envs.residual_in_place import RESIDUAL_IN_PLACE

RESIDUAL_TASKS = (RESIDUAL_IN_PLACE, RESIDUAL_FORWARD)
HOP_CYCLE_TASKS = (HOP_IN_PLACE, *RESIDUAL_TASKS)


def hop_in_place_params(env: Any, speed: float, policy: str) -> HopInPlaceParams:
    """The env's params for `--policy policy`, which is for hop_in_place only and takes no --speed."""
    params = env.unwrapped.params
    if not isinstance(params, HopInPlaceParams):
        raise ValueError(f"--policy {policy} is for --task {HOP_IN_PLACE.name}")
    if speed != 0.0:
        raise ValueError(f"--task {HOP_IN_PLACE.name} hops in place: --speed must be 0, got {speed}")
    return params


def do_nothing_policy(env: Any, speed: float) -> ConstantAction:
    """--policy do_nothing on hop_in_place: the do-nothing action every hop (offset 0, the default thrust)."""
    return ConstantAction(do_nothing_action(hop_in_place_params(env, speed, "do_nothing")))


PLACEMENT_BY_SPEED = (0.02, 0.02)  # m, m per m/s: placement_by_speed's offset at rest, and its growth with speed


def placement_by_speed(env: Any, speed: float) -> Callable[[np.ndarray], int]:
    """--policy placement_by_speed on hop_in_place: a hand-made placement that depends on the state, the baseline
    beside the constant ones under strong pushes. The foot lands 2 cm + 2 cm per m/s of the speed at lift-off ahead
    along the velocity, rounded to the nearest offset level (hop_in_place.yaml's: +2 cm up to 0.5 m/s, +4 cm up to
    1.5 m/s, +6 cm up to 2.5 m/s), with the default thrust. A Q-table over either of the task's state keys can hold
    it up to 1.5 m/s, not above: their top speed bins (above 0.5 and 0.8 m/s) take one offset for every faster hop."""
    params = hop_in_place_params(env, speed, "placement_by_speed")
    levels = np.array(offsets(params))
    thrust = do_nothing_action(params) % params.thrust_levels
    at_rest, per_speed = PLACEMENT_BY_SPEED

    def policy(observation: np.ndarray) -> int:
        offset = int(np.argmin(np.abs(levels - (at_rest + per_speed * float(observation[2])))))
        return offset * params.thrust_levels + thrust
    return policy


def zero_residual(env: Any, speed: float) -> Any:
    """--policy do_nothing on the residual tasks (and controller, under controller_params): no residual every hop.
    The commanded speed is the task's target_speed; --speed must be 0 or equal it."""
    params = env.unwrapped.params
    if speed not in (0.0, params.target_speed):
        raise ValueError(f"--task {env.unwrapped.task.name} is commanded its target_speed "
                         f"({params.target_speed} m/s): --speed must be 0 or that, got {speed}")
    action = np.zeros(2, dtype=np.float32)
    return lambda observation: action


def controller_params(task: TaskSpec[Any], params: Any) -> Any:
    """--policy controller's params: the hop-cycle tasks' with the controller's own laws on, the others' in
    action_mode targets at the control period; end_to_end's as they are (targets at 5 ms: the teacher's period)."""
    if task is END_TO_END:
        return params
    if task in HOP_CYCLE_TASKS:
        return hop_cycle_controller_params(params)
    return step_controller_params(task, params)


def do_nothing(env: Any, speed: float) -> Any:
    if env.unwrapped.task is END_TO_END:  # the targets of the crouch every step: hold still
        return ConstantAction(np.zeros(env.action_space.shape, dtype=env.action_space.dtype))
    if env.unwrapped.task in RESIDUAL_TASKS:
        return zero_residual(env, speed)
    return do_nothing_policy(env, speed)


def controller(env: Any, speed: float) -> Any:
    if env.unwrapped.task in HOP_CYCLE_TASKS:
        return do_nothing(env, speed)
    if env.unwrapped.task is END_TO_END:  # the teacher's gains at its 5 ms period
        return five_ms_controller(env, speed)
    return ControllerPolicy(env, speed)


POLICIES = {
    "controller": ScriptedPolicy(controller_params, controller),
    "do_nothing": ScriptedPolicy(lambda task, params: params, do_nothing),
    "placement_by_speed": ScriptedPolicy(lambda task, params: params, placement_by_speed),
    "random": ScriptedPolicy(lambda task, params: params,
                             lambda env, speed: random_actions(env.action_space, np.random.default_rng(0)))}
