"""The greedy table checked during training, and the best one kept (the params' `selection`).

A tabular run under pushes swings: its table after one hundred episodes may be upright in 60 % of pushed
episodes, after the next hundred in 30 %, and the table at the end is whichever came last. With `selection/every`
> 0 the trainer stops every that many episodes and plays its greedy table (no exploration, no learning; ties broken
by an RNG seeded with `selection/seed`) for `selection/episodes` episodes from a reset seeded with `selection/seed`,
so every check plays the same starts and the same pushes (robot_rl.envs.pushes). The mean of the task's headline
metric over them is the table's score; a score above every earlier one writes the table to qtable_best.json, a
checkpoint of the run's format that evaluate.py plays (`--run RUN/qtable_best.json`). Each check is a row of
selection.csv. The training env's next reset is seeded from (the run's seed, the episode), so the training episodes
after a check do not repeat the check's.

A check runs on an episode count that is a multiple of `every` (the last one too), after a checkpoint of the table it
checks; its result is in the next checkpoint. A run stopped during a check resumes from that checkpoint and plays
the check again: the same table on the same episodes. Choose a seed evaluation does not use: the best table is picked
on the check's episodes, and its score on them is optimistic; evaluate.py's figures on other seeds are not.
"""
from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from ...atomic import write_text_atomic
from ...params import TableSelection
from ...task import Episode, StateKey, TaskSpec, play_episode
from .qlearn import QLearn

SELECTION_CSV = "selection.csv"
BEST_CHECKPOINT = "qtable_best.json"
COLUMNS = ("episode", "score", "mean_return", "best_score", "best_episode")


@dataclass
class SelectionState:
    """Where the checks stand: the last episode count checked (0: none yet), the best score and its episode count."""

    checked_at: int = 0
    best_score: float = -math.inf
    best_episode: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {"checked_at": self.checked_at, "best_score": None if self.best_score == -math.inf else self.best_score,
                "best_episode": self.best_episode}

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> SelectionState:
        """Inverse of to_dict() (ValueError on a wrong value)."""
        checked_at, best, best_episode = values["checked_at"], values["best_score"], values["best_episode"]
        if not (isinstance(checked_at, int) and isinstance(best_episode, int) and 0 <= best_episode <= checked_at):
            raise ValueError(f"selection {values!r}: checked_at and best_episode must be ints, 0 <= best_episode <= "
                             "checked_at")
        if best is not None and not isinstance(best, (int, float)):
            raise ValueError(f"selection best_score {best!r} is not a number")
        return cls(checked_at, -math.inf if best is None else float(best), best_episode)


def check_due(selection: TableSelection, state: SelectionState, episode: int, nepisodes: int) -> bool:
    """Whether the table after `episode` training episodes is to be checked (not yet checked, and a multiple of
    `every` or the run's last episode)."""
    if not selection.every or episode <= state.checked_at or episode == 0:
        return False
    return episode % selection.every == 0 or episode >= nepisodes


def play_greedy(env: gymnasium.Env[Any, Any], qlearn: QLearn, state_key: StateKey, selection: TableSelection,
                nsteps: int, running_step: float) -> list[Episode]:
    """`selection.episodes` episodes of `qlearn`'s greedy policy, the first reset seeded with `selection.seed`.
    Reads `qlearn`, never changes it (its tie breaks use an RNG of its own)."""
    greedy = QLearn.from_dict(qlearn.to_dict())
    greedy.rng.seed(selection.seed)

    def act(observation: Any) -> Any:
        return greedy.greedy_action(state_key.key(observation))
    return [play_episode(env, act, running_step, seed=selection.seed if i == 0 else None, max_steps=nsteps)
            for i in range(selection.episodes)]


def score(episodes: Sequence[Episode], task: TaskSpec[Any]) -> tuple[float, float]:
    """(the mean of the task's headline metric, the mean return) over `episodes`."""
    headline = [float(task.metrics(episode)[task.headline_metric]) for episode in episodes]
    return float(np.mean(headline)), float(np.mean([episode.return_ for episode in episodes]))


def training_reseed(seed: int, episode: int) -> int:
    """The seed of the training env's first reset after a check at `episode`: from (the run's seed, the episode)."""
    return int(np.random.SeedSequence([seed, episode]).generate_state(1)[0])


class SelectionLog:
    """selection.csv of the run folder `path`: one row per check, rewritten whole (atomically) each time."""

    def __init__(self, path: Path):
        self.path = path / SELECTION_CSV

    def rows(self) -> list[list[str]]:
        """The rows after the header ([] without a file); ValueError naming the file if it is not ours."""
        try:
            text = self.path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return []
        table = list(csv.reader(io.StringIO(text)))
        if not table or tuple(table[0]) != COLUMNS:
            raise ValueError(f"{self.path}: not a selection log (its header is not {','.join(COLUMNS)})")
        return table[1:]

    def write(self, rows: Sequence[Sequence[Any]]) -> None:
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows([COLUMNS, *rows])
        write_text_atomic(self.path, buf.getvalue())

    def append(self, row: Sequence[Any]) -> None:
        self.write([*self.rows(), row])

    def keep_until(self, episode: int) -> None:
        """Drop the rows of checks after `episode` (a resume from a checkpoint taken before them)."""
        rows = self.rows()
        kept = [row for row in rows if int(row[0]) <= episode]
        if len(kept) != len(rows):
            self.write(kept)
