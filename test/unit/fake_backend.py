"""A Backend without physics for the task tests: it hands out the readings a test scripts and records
every reset, placement, command and step the env makes."""
from __future__ import annotations

import numpy as np

from robot_rl import Backend, Readings


class FakeBackend(Backend):
    """Returns `at_reset` on reset and the next of `script` on each step (then `after` forever)."""

    time_step = 0.001

    def __init__(self, at_reset: Readings, script=(), after: Readings | None = None, config=None):
        self.at_reset = at_reset
        self.config = config                          # the RobotConfig a task's placement reads (spawn pose)
        self.placements: list[tuple] = []             # (base FrameState, joint positions) of each place call
        self.script = list(script)
        self.after = after or at_reset
        self.commands: list[tuple[str, float]] = []   # (controller, value) in call order
        self.steps: list[int] = []                    # physics_steps of each step call
        self.resets: list[bool] = []                  # restart_time of each reset call
        self.closed = False

    def reset(self, restart_time: bool = False) -> Readings:
        self.resets.append(restart_time)
        return self.at_reset

    def place(self, base, joints) -> None:
        self.placements.append((base, dict(joints)))

    def set_command(self, controller: str, value: float) -> None:
        self.commands.append((controller, value))

    def step(self, physics_steps: int) -> Readings:
        self.steps.append(physics_steps)
        return self.script.pop(0) if self.script else self.after

    def render(self, width: int, height: int) -> np.ndarray:
        return np.zeros((height, width, 3), dtype=np.uint8)

    def close(self) -> None:
        self.closed = True
