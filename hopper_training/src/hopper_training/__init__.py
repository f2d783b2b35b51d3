"""The monoped hopper's training: the Monoped-v0 (stay up), MonopedHop-v0, MonopedHopInPlace-v0 (hop in place,
one decision per hop; MonopedHopLevel-v0 is its former id, registered as an alias) and the residual
(MonopedResidualInPlace-v0, MonopedResidualForward-v0: a deep agent's residual on the hopping controller) tasks,
and MonopedEndToEnd-v0 (a learned policy alone sets the joint targets every 5 ms).

Importing this package registers them with gymnasium:
`gymnasium.make("Monoped-v0", backend="ros" | "direct")`.
"""
from typing import Any

from robot_rl import TaskSpec, register_tasks

from .envs.end_to_end import END_TO_END
from .envs.hop import HOP
from .envs.hop_in_place import HOP_IN_PLACE
from .envs.residual_forward import RESIDUAL_FORWARD
from .envs.residual_in_place import RESIDUAL_IN_PLACE
from .envs.stay_up import STAY_UP

TASKS: list[TaskSpec[Any]] = [STAY_UP, HOP, HOP_IN_PLACE, RESIDUAL_IN_PLACE, RESIDUAL_FORWARD, END_TO_END]
register_tasks(*TASKS)
