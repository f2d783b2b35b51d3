"""The moving cube's training: CubeRLUtils (seed 000), the MovingCubeOneDiskWalk-v0 task, Q-learning.

Importing this package registers MovingCubeOneDiskWalk-v0 with gymnasium:
`gymnasium.make("MovingCubeOneDiskWalk-v0", backend="ros" | "direct")`.
"""
from typing import Any

from robot_rl import TaskSpec, register_tasks

from .envs.one_disk_walk import ONE_DISK_WALK

TASKS: list[TaskSpec[Any]] = [ONE_DISK_WALK]
register_tasks(*TASKS)
