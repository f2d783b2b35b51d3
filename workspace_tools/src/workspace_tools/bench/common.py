"""What every part of ./ws bench shares: its sections, the robots it measures and their task params."""
from __future__ import annotations

import importlib
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_rl import TaskParams, TaskSpec, find_task
from workspace_tools.robots import ROBOTS as ROBOT_REGISTRY

SECTIONS = ("lockstep", "scaling", "deep", "gazebo", "training", "distributed", "sweeps", "rllib")
SWEEP_EPISODES, SWEEP_EVAL_EPISODES = 400, 5
SCALING_ENVS = (1, 2, 4)
DISTRIBUTED_ENVS = (1, 2)
RECOVERY_STEPS_BEFORE_LOSS = 50  # vector steps of the two actors before the second node is killed


@dataclass(frozen=True)
class BenchRobot:
    task: TaskSpec[Any]               # the task the robot is measured on
    sim_seconds: float                # sim time per lockstep measurement (env steps = this / running_step)
    gazebo_steps: dict[float, int]    # Gazebo-style steps per real-time factor


def _default_task(robot: str) -> TaskSpec[Any]:
    """The task the robot's main.launch trains by default (workspace_tools.robots)."""
    spec = ROBOT_REGISTRY[robot]
    return find_task(list(importlib.import_module(spec.package).TASKS), spec.default_task)


ROBOTS = {"cube": BenchRobot(_default_task("cube"), 180.0, {1.0: 20, 0.0: 50}),
          "hopper": BenchRobot(_default_task("hopper"), 60.0, {1.0: 100, 0.0: 200})}
CEILING_WARNING = 1.5  # 2 independent direct processes below this speedup: the run did not have two free cores
DEEP_STEPS = 4000  # env steps of DQN learning (its first learning_starts only collect)
END_TO_END_STEPS = 2000  # env steps of the hopper's end_to_end task (10 s of sim at its 5 ms), the teacher acting
# agent bc_dagger's tiny budget: 4 episodes of at most 2 s (1600 samples at most), a few epochs of each stage
BC_DAGGER_TINY = dict(bc_episodes=2, bc_epochs=5, dagger_rounds=1, dagger_episodes=2, dagger_epochs=5, horizon_s=2.0)


def bench_params(robot: str, running_step: float) -> TaskParams:
    """The robot's task params from its config, with the control period the bench measures."""
    params = ROBOTS[robot].task.default_params()
    return params if params.running_step == running_step else params.with_changes("bench", running_step=running_step)


def stat_fields(pid: int | str) -> list[str]:
    """A process's /proc/PID/stat after its name: [0] state, [1] parent PID, [11] user and [12] system CPU ticks."""
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()


def cpu_seconds(fields: list[str]) -> float:
    """CPU seconds (user + system) from a process's stat_fields."""
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def lockstep_speedup_bound(step_times: Sequence[float], n: int = 2) -> float:
    """The most a vector env that steps n envs together can gain over one env with these step times: each
    of its steps lasts as long as the slowest of n, so n x mean / E[max of n] (the n steps drawn
    independently from these times; the expectation is exact over them)."""
    ordered, count = sorted(step_times), len(step_times)
    expected_max = sum(t * ((k / count) ** n - ((k - 1) / count) ** n) for k, t in enumerate(ordered, 1))
    return n * (sum(ordered) / count) / expected_max

