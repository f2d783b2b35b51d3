"""Training results on disk: <root>/<results name>/<run>/ plus a <root>/<results name>/latest symlink.

A run directory holds .lock, params.yaml, episodes.csv, its agent's checkpoint (robot_rl.agents: qtable.json
for tabular Q-learning; agent.json beside Stable-Baselines3's model.zip for a deep agent),
learning_curve.png, summary.json and, once trained, video.mp4 (the greedy policy). Everything except
the append-only episodes.csv is written atomically; no pickle.
A trainer that creates or resumes a run holds an exclusive lock (flock) on its .lock file for the rest of
its process's life, and the kernel drops it when the process ends however it ends: a second trainer of
the same run folder is refused (RunLockedError) before it writes anything.
episodes.csv has the columns of every task (COLUMNS) followed by the task's own metrics.
"""
from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from ..atomic import StrPath, hold_lock, symlink_atomic, write_bytes_atomic, write_json_atomic, write_text_atomic
from .plots import learning_curve_png

COLUMNS = ("episode", "steps", "return", "epsilon", "sim_time", "wall_time")
LATEST = "latest"
QTABLE_CHECKPOINT = "qtable.json"
DEEP_CHECKPOINT = "agent.json"
LOCK_FILE = ".lock"
T = TypeVar("T")


class RunLockedError(ValueError):
    """Another process trains this run folder."""


class RunFileError(ValueError):
    """A file of the run beside the checkpoint (a deep agent's model.zip) cannot be used; str() names it."""


@dataclass(frozen=True)
class EpisodeRecord:
    """One episodes.csv row; `return_` is the "return" column. Times are seconds since run start."""
    episode: int  # 1-based
    steps: int
    return_: float
    epsilon: float
    sim_time: float
    wall_time: float
    metrics: Mapping[str, float | bool] = field(default_factory=dict)  # the task's, in its columns' order

    def row(self) -> list[Any]:
        return [self.episode, self.steps, self.return_, self.epsilon, self.sim_time, self.wall_time,
                *self.metrics.values()]


def _metric_value(text: str) -> float | bool:
    """A metric cell: "True"/"False" (a rate's episode) or a number."""
    return {"True": True, "False": False}[text] if text in ("True", "False") else float(text)


def aggregate(values: Mapping[str, Sequence[float | bool]]) -> dict[str, float | None]:
    """Per metric over episodes: `<name>_rate` for yes/no metrics, `mean_<name>` for numbers (None if empty)."""
    out: dict[str, float | None] = {}
    for name, column in values.items():
        rate = bool(column) and all(isinstance(v, bool) for v in column)
        out[f"{name}_rate" if rate else f"mean_{name}"] = float(np.mean(column)) if len(column) else None
    return out


def _check_name(what: str, name: str) -> None:
    if not name or name in (".", "..", LATEST) or "/" in name:
        raise ValueError(f"invalid {what} name {name!r}")


class RunDirectory:
    """One training run's directory; `robot` (its results name) and `name` are taken from its path.
    `checkpoint_name` is the checkpoint's file: qtable.json, or agent.json for a deep agent."""

    def __init__(self, path: StrPath, checkpoint_name: str = QTABLE_CHECKPOINT) -> None:
        self.path = Path(path)
        self.robot = self.path.parent.name
        self.name = self.path.name
        self.checkpoint_name = checkpoint_name

    @property
    def episodes_csv(self) -> Path:
        return self.path / "episodes.csv"

    @property
    def params_yaml(self) -> Path:
        return self.path / "params.yaml"

    @property
    def qtable_json(self) -> Path:
        return self.path / QTABLE_CHECKPOINT

    @property
    def checkpoint_json(self) -> Path:
        return self.path / self.checkpoint_name

    @property
    def model_zip(self) -> Path:
        """A deep agent's model, in Stable-Baselines3's format."""
        return self.path / "model.zip"

    @property
    def learning_curve_png(self) -> Path:
        return self.path / "learning_curve.png"

    @property
    def video_mp4(self) -> Path:
        return self.path / "video.mp4"

    @property
    def summary_json(self) -> Path:
        return self.path / "summary.json"

    @classmethod
    def create(cls, root: StrPath, robot: str, params: dict[str, Any], metric_names: Sequence[str] = (),
               run_name: str | None = None, checkpoint_name: str = QTABLE_CHECKPOINT) -> RunDirectory:
        """Make a new run directory and point `latest` at it.

        Default name: UTC "%Y%m%d-%H%M%S", with "-1", "-2", ... appended if taken. An explicit
        `run_name` that already exists raises FileExistsError (a run is never overwritten); a `latest` that is
        not a symlink, ValueError naming it, before anything is made.
        """
        _check_name("robot", robot)
        robot_dir = Path(root) / robot
        latest = robot_dir / LATEST
        if latest.exists() and not latest.is_symlink():  # checked before the run folder: nothing left behind
            raise ValueError(f"{latest} is a {'folder' if latest.is_dir() else 'file'}, not the link to the newest "
                             f"run kept there: move it away (nothing was written)")
        robot_dir.mkdir(parents=True, exist_ok=True)
        if run_name is not None:
            _check_name("run", run_name)
            name = run_name
            (robot_dir / name).mkdir()
        else:
            base = datetime.now(UTC).strftime("%Y%m%d-%H%M%S")
            name, n = base, 0
            while True:
                try:
                    (robot_dir / name).mkdir()
                    break
                except FileExistsError:
                    n += 1
                    name = f"{base}-{n}"
        run = cls(robot_dir / name, checkpoint_name)
        run.lock()
        write_text_atomic(run.params_yaml, yaml.safe_dump(params, sort_keys=True, default_flow_style=False))
        write_text_atomic(run.episodes_csv, ",".join((*COLUMNS, *metric_names)) + "\n")
        symlink_atomic(name, robot_dir / LATEST)
        return run

    @classmethod
    def named(cls, root: StrPath, robot: str, name: str, checkpoint_name: str = QTABLE_CHECKPOINT) -> RunDirectory:
        """The run <root>/<robot>/<name>; FileNotFoundError naming the runs there if there is none."""
        _check_name("run", name)
        robot_dir = Path(root) / robot
        if not (robot_dir / name).is_dir():
            runs = sorted(p.name for p in robot_dir.iterdir() if p.is_dir() and p.name != LATEST) \
                if robot_dir.is_dir() else []
            raise FileNotFoundError(f"no run {name!r} under {robot_dir} (runs: {', '.join(runs) or 'none'})")
        return cls(robot_dir / name, checkpoint_name)

    @classmethod
    def latest(cls, root: StrPath, robot: str, checkpoint_name: str = QTABLE_CHECKPOINT) -> RunDirectory:
        """The run <root>/<robot>/latest points to."""
        robot_dir = Path(root) / robot
        link = robot_dir / LATEST
        if not link.is_symlink() or not link.is_dir():
            raise FileNotFoundError(f"no previous run under {robot_dir}: start without resume")
        return cls(robot_dir / Path(os.readlink(link)).name, checkpoint_name)

    def lock(self) -> None:
        """Hold the run's lock for the rest of this process's life (a no-op if it already does);
        RunLockedError naming the folder if another process holds it."""
        path = self.path.resolve()
        if not hold_lock(path / LOCK_FILE):
            raise RunLockedError(f"{path}: another process is training this run (it holds {path / LOCK_FILE}); "
                                 f"wait for it to end, or train another run")

    @property
    def metric_names(self) -> tuple[str, ...]:
        """The task metrics' columns of episodes.csv."""
        return self._header()[len(COLUMNS):]

    def _header(self) -> tuple[str, ...]:
        with open(self.episodes_csv, encoding="utf-8") as f:
            header = tuple(next(csv.reader([f.readline()]), []))
        if header[:len(COLUMNS)] != COLUMNS:
            raise ValueError(f"{self.episodes_csv}: header must start with {','.join(COLUMNS)}")
        return header

    def append_episode(self, record: EpisodeRecord) -> None:
        """Append one row to episodes.csv, flushed and fsynced."""
        if record.episode < 1:
            raise ValueError(f"episode numbers are 1-based, got {record.episode}")
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow(record.row())
        with open(self.episodes_csv, "a", encoding="utf-8", newline="") as f:
            f.write(buf.getvalue())
            f.flush()
            os.fsync(f.fileno())

    def read_episodes(self) -> list[EpisodeRecord]:
        """All complete rows of episodes.csv (a torn last line without newline, left by a crash
        in the middle of append_episode, is ignored)."""
        text = self.episodes_csv.read_text(encoding="utf-8")
        lines = text.split("\n")[:-1]  # drops "" after the final newline, or a torn last line
        rows = list(csv.reader(lines))
        header = self._header()
        records = []
        for lineno, row in enumerate(rows[1:], start=2):
            try:
                if len(row) != len(header):
                    raise ValueError(f"{len(row)} columns, the header has {len(header)}")
                episode, steps, ret, eps, sim_time, wall_time, *metrics = row
                named = dict(zip(header[len(COLUMNS):], map(_metric_value, metrics)))
                records.append(EpisodeRecord(int(episode), int(steps), float(ret), float(eps), float(sim_time),
                                             float(wall_time), named))
            except ValueError as e:
                raise ValueError(f"{self.episodes_csv}:{lineno}: bad row {row!r}: {e}") from None
        return records

    def checkpoint(self, state: dict[str, Any]) -> None:
        """Atomically write the checkpoint (qtable.json): `state` (must hold "episode") plus "written_at"."""
        if not isinstance(state.get("episode"), int) or state["episode"] < 0:
            raise ValueError(f"checkpoint state needs an int 'episode' >= 0, got {state.get('episode')!r}")
        write_json_atomic(self.checkpoint_json, {**state, "written_at": datetime.now(UTC).isoformat()})

    def load_checkpoint(self) -> dict[str, Any]:
        """The checkpoint as a dict; FileNotFoundError or ValueError naming the file if it cannot be."""
        path = self.checkpoint_json
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise FileNotFoundError(f"no checkpoint {path}: nothing to resume from") from None
        except UnicodeDecodeError:
            raise ValueError(f"{path}: not a checkpoint (not UTF-8 text)") from None
        try:
            state = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"{path}: invalid JSON: {e}") from None
        if not isinstance(state, dict):
            raise ValueError(f"{path}: not a checkpoint (a JSON {type(state).__name__}, not an object)")
        return state

    def prepare_resume(self, restore: Callable[[dict[str, Any]], T]) -> T:
        """Load the checkpoint and restore it with `restore` (which raises ValueError on anything wrong,
        naming the checkpoint, or a RunFileError naming another file of the run),
        then drop episodes.csv rows logged after it (they will be re-run). Nothing is written unless
        the whole checkpoint restored. Takes the run's lock first (RunLockedError if another process
        trains it)."""
        self.lock()
        state = self.load_checkpoint()
        try:
            restored = restore(state)
        except RunFileError:
            raise
        except (KeyError, TypeError, ValueError) as error:
            reason = f"missing {error}" if isinstance(error, KeyError) else str(error)
            raise ValueError(f"{self.checkpoint_json}: not a usable checkpoint: {reason}") from None
        episode = state["episode"]
        records = self.read_episodes()
        if len([r for r in records if r.episode <= episode]) < episode:
            raise ValueError(f"{self.episodes_csv} has {len(records)} episodes, fewer than the {episode} of the "
                             f"checkpoint {self.checkpoint_json}")
        header = ",".join(self._header()) + "\n"
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows(r.row() for r in records if r.episode <= episode)
        write_text_atomic(self.episodes_csv, header + buf.getvalue())
        return restored

    def write_learning_curve(self, *metrics: str) -> None:
        """Plot return, the task's `metrics` (if given) and epsilon per episode, each with its moving
        average over MOVING_AVERAGE episodes, to learning_curve.png."""
        records = self.read_episodes()
        panels = [("return", [r.return_ for r in records])]
        for metric in metrics:
            panels.append((metric, [float(r.metrics.get(metric, np.nan)) for r in records]))
        panels.append(("epsilon", [r.epsilon for r in records]))
        png = learning_curve_png([r.episode for r in records], panels, f"{self.robot} / {self.name}")
        write_bytes_atomic(self.learning_curve_png, png)

    def write_summary(self, summary: dict[str, Any]) -> None:
        write_json_atomic(self.summary_json, summary)
