"""Training results on disk: <root>/<robot>/<run>/ plus a <root>/<robot>/latest symlink.

A run directory holds params.yaml, episodes.csv, qtable.json (checkpoint), learning_curve.png and
summary.json. Everything except the append-only episodes.csv is written atomically; no pickle.
"""
from __future__ import annotations

import csv
import io
import json
import os
from dataclasses import astuple, dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from robot_rl.atomic import (StrPath, symlink_atomic, write_bytes_atomic, write_json_atomic,
                             write_text_atomic)

COLUMNS = ("episode", "steps", "return", "epsilon", "sim_time", "wall_time")
LATEST = "latest"


@dataclass(frozen=True)
class EpisodeRecord:
    """One episodes.csv row; `return_` is the "return" column. Times are seconds since run start."""
    episode: int  # 1-based
    steps: int
    return_: float
    epsilon: float
    sim_time: float
    wall_time: float


def _csv_text(records: list[EpisodeRecord]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(COLUMNS)
    writer.writerows(astuple(r) for r in records)
    return buf.getvalue()


def _check_name(what: str, name: str) -> None:
    if not name or name in (".", "..", LATEST) or "/" in name:
        raise ValueError(f"invalid {what} name {name!r}")


class RunDirectory:
    """One training run's directory; `robot` and `name` are taken from its path."""

    def __init__(self, path: StrPath) -> None:
        self.path = Path(path)
        self.robot = self.path.parent.name
        self.name = self.path.name

    @property
    def episodes_csv(self) -> Path:
        return self.path / "episodes.csv"

    @property
    def params_yaml(self) -> Path:
        return self.path / "params.yaml"

    @property
    def qtable_json(self) -> Path:
        return self.path / "qtable.json"

    @property
    def learning_curve_png(self) -> Path:
        return self.path / "learning_curve.png"

    @property
    def summary_json(self) -> Path:
        return self.path / "summary.json"

    @classmethod
    def create(cls, root: StrPath, robot: str, params: dict[str, Any],
               run_name: str | None = None) -> RunDirectory:
        """Make a new run directory and point `latest` at it.

        Default name: UTC "%Y%m%d-%H%M%S", with "-1", "-2", ... appended if taken. An explicit
        `run_name` that already exists raises FileExistsError (a run is never overwritten).
        """
        _check_name("robot", robot)
        robot_dir = Path(root) / robot
        robot_dir.mkdir(parents=True, exist_ok=True)
        if run_name is not None:
            _check_name("run", run_name)
            name = run_name
            (robot_dir / name).mkdir()
        else:
            base = datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S")
            name, n = base, 0
            while True:
                try:
                    (robot_dir / name).mkdir()
                    break
                except FileExistsError:
                    n += 1
                    name = f"{base}-{n}"
        run = cls(robot_dir / name)
        write_text_atomic(run.params_yaml, yaml.safe_dump(params, sort_keys=True, default_flow_style=False))
        write_text_atomic(run.episodes_csv, _csv_text([]))
        symlink_atomic(name, robot_dir / LATEST)
        return run

    @classmethod
    def latest(cls, root: StrPath, robot: str) -> RunDirectory:
        """The run <root>/<robot>/latest points to."""
        robot_dir = Path(root) / robot
        link = robot_dir / LATEST
        if not link.is_symlink() or not link.is_dir():
            raise FileNotFoundError(f"no previous run under {robot_dir}: start without resume")
        return cls(robot_dir / Path(os.readlink(link)).name)

    def append_episode(self, record: EpisodeRecord) -> None:
        """Append one row to episodes.csv, flushed and fsynced."""
        if record.episode < 1:
            raise ValueError(f"episode numbers are 1-based, got {record.episode}")
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow(astuple(record))
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
        if not rows or tuple(rows[0]) != COLUMNS:
            raise ValueError(f"{self.episodes_csv}: header must be {','.join(COLUMNS)}")
        records = []
        for lineno, row in enumerate(rows[1:], start=2):
            try:
                episode, steps, ret, eps, sim_time, wall_time = row
                records.append(EpisodeRecord(int(episode), int(steps), float(ret), float(eps),
                                             float(sim_time), float(wall_time)))
            except ValueError as e:
                raise ValueError(f"{self.episodes_csv}:{lineno}: bad row {row!r}: {e}") from None
        return records

    def checkpoint(self, state: dict[str, Any]) -> None:
        """Atomically write qtable.json: `state` (must hold "episode") plus "written_at"."""
        if not isinstance(state.get("episode"), int) or state["episode"] < 0:
            raise ValueError(f"checkpoint state needs an int 'episode' >= 0, got {state.get('episode')!r}")
        write_json_atomic(self.qtable_json,
                          {**state, "written_at": datetime.now(timezone.utc).isoformat()})

    def load_checkpoint(self) -> dict[str, Any]:
        try:
            text = self.qtable_json.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise FileNotFoundError(f"no checkpoint {self.qtable_json}: nothing to resume from") from None
        try:
            return json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"{self.qtable_json}: invalid JSON: {e}") from None

    def prepare_resume(self) -> dict[str, Any]:
        """Load the checkpoint and drop episodes.csv rows logged after it (they will be re-run)."""
        state = self.load_checkpoint()
        kept = [r for r in self.read_episodes() if r.episode <= state["episode"]]
        write_text_atomic(self.episodes_csv, _csv_text(kept))
        return state

    def write_learning_curve(self) -> None:
        """Plot return per episode and its moving average (window min(50, n)) to learning_curve.png."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        records = self.read_episodes()
        fig, ax = plt.subplots(figsize=(8, 4.5))
        try:
            if records:
                x = np.array([r.episode for r in records])
                y = np.array([r.return_ for r in records])
                window = min(50, len(y))
                avg = np.convolve(y, np.ones(window) / window, mode="valid")
                ax.plot(x, y, ".", alpha=0.4, label="return")
                ax.plot(x[window - 1:], avg, "-", label=f"moving average ({window})")
                ax.legend(loc="best")
            else:
                ax.text(0.5, 0.5, "no episodes yet", ha="center", va="center", transform=ax.transAxes)
            ax.set_xlabel("episode")
            ax.set_ylabel("return")
            ax.set_title(f"{self.robot} / {self.name}")
            ax.grid(True, alpha=0.3)
            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=100)
        finally:
            plt.close(fig)
        write_bytes_atomic(self.learning_curve_png, buf.getvalue())

    def write_summary(self, summary: dict[str, Any]) -> None:
        write_json_atomic(self.summary_json, summary)
