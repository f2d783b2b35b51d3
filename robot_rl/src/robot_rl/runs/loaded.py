"""A trained run as its agent's policy loader receives it: its checkpoint, agent, task and params."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from ..params import Params
from ..task import TaskSpec


class RunAgent(Protocol):
    """What a loaded run knows of its agent (robot_rl.agents.registry.AgentSpec keeps it)."""

    @property
    def name(self) -> str: ...

    def load_params_from(self, values: Any, source: str) -> Params | None: ...


class LoadedRun:
    """A run's checkpoint file (`path`), its agent, its task, and its params (`params`, read from `params_file`),
    checked against each other by whoever loaded them (robot_rl.evaluation.TrainedRun)."""

    def __init__(self, path: Path, agent: RunAgent, task: TaskSpec[Any], params_file: Path, params: Any):
        self.path, self.agent, self.task, self.params_file, self.params = path, agent, task, params_file, params
