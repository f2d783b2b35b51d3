"""The monoped hopper's training: the Monoped-v0 (stay up), MonopedHop-v0 and MonopedHopLevel-v0 (hop in place,
one decision per hop) tasks, Q-learning.

Importing this package registers them with gymnasium:
`gymnasium.make("Monoped-v0", backend="ros" | "direct")`.
"""
from typing import Any

from robot_rl.task import TaskSpec, register_tasks

from .hop import HOP
from .hop_level import HOP_LEVEL
from .monoped_env import STAY_UP

TASKS: list[TaskSpec[Any]] = [STAY_UP, HOP, HOP_LEVEL]
register_tasks(*TASKS)
