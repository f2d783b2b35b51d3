"""The monoped hopper's training: the Monoped-v0 (stay up), MonopedHop-v0, MonopedHopLevel-v0 (hop in place,
one decision per hop) and the residual (MonopedResidualInPlace-v0, MonopedResidualForward-v0: a deep agent's
residual on the hopping controller) tasks.

Importing this package registers them with gymnasium:
`gymnasium.make("Monoped-v0", backend="ros" | "direct")`.
"""
from typing import Any

from robot_rl.task import TaskSpec, register_tasks

from .hop import HOP
from .hop_level import HOP_LEVEL
from .hop_residual import RESIDUAL_FORWARD, RESIDUAL_IN_PLACE
from .monoped_env import STAY_UP

TASKS: list[TaskSpec[Any]] = [STAY_UP, HOP, HOP_LEVEL, RESIDUAL_IN_PLACE, RESIDUAL_FORWARD]
register_tasks(*TASKS)
