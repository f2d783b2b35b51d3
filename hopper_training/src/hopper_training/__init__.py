"""The monoped hopper's training: the Monoped-v0 (stay up) and MonopedHop-v0 tasks, Q-learning.

Importing this package registers both with gymnasium:
`gymnasium.make("Monoped-v0", backend="ros" | "direct")`.
"""
from typing import Any

from robot_rl.task import TaskSpec, register_tasks

from .hop import HOP
from .monoped_env import STAY_UP

TASKS: list[TaskSpec[Any]] = [STAY_UP, HOP]
register_tasks(*TASKS)
