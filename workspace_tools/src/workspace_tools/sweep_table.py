"""A sweep's table (markdown and CSV) and its plot of every trial's learning curve with the mean.

One `TrialResult` per trial, read from its run folder (summary.json, evaluation.json, episodes.csv).
The table has one row per trial: its name, seed, the parameters the sweep varies, episodes, env steps,
wall time, the training metrics over its last 100 episodes (summary.json), and the greedy and random
policies' metrics (robot_rl.evaluation). With several trials per combination of parameters (seeds), a
second table gives each combination's greedy headline metric: mean, min and max over its seeds.
"""
from __future__ import annotations

import csv
import io
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from robot_rl import MOVING_AVERAGE, moving_average, write_bytes_atomic, write_text_atomic


@dataclass(frozen=True)
class TrialResult:
    name: str
    seed: int
    params: dict[str, Any]                  # the parameters the sweep varies, by name
    episodes: int
    env_steps: int
    wall_time_s: float
    train: dict[str, float | None]          # summary.json's metrics_last_100
    greedy: dict[str, float | None]         # evaluation.json's
    random: dict[str, float | None]
    curve: list[float] = field(default_factory=list)  # the headline metric per training episode

    def group(self) -> tuple[Any, ...]:
        return tuple(self.params.values())


def _cell(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1e4 else f"{value:.0f}"
    return str(value)


def _columns(results: Sequence[TrialResult]) -> tuple[list[str], list[str], list[str], list[str]]:
    """The varied parameters and the training, greedy and random metric names, in first-seen order."""
    def names(which: str) -> list[str]:
        return list(dict.fromkeys(k for r in results for k in getattr(r, which)))
    return names("params"), names("train"), names("greedy"), names("random")


def _stats(values: list[float]) -> str:
    if not values:
        return "n/a"
    return f"{statistics.fmean(values):.3g} ({min(values):.3g}-{max(values):.3g})"


def table_markdown(results: Sequence[TrialResult], title: str, greedy_key: str) -> str:
    """The trials' table, then (with several seeds per combination) the combinations' summary."""
    params, train, greedy, random = _columns(results)
    head = ["trial", "seed", *params, "episodes", "env steps", "wall time (s)", *(f"training {k}" for k in train),
            *(f"greedy {k}" for k in greedy), *(f"random {k}" for k in random)]
    lines = [title, "", "| " + " | ".join(head) + " |", "|---|---:|" + "---:|" * (len(head) - 2)]
    for r in results:
        cells = [r.name, r.seed, *(r.params.get(k) for k in params), r.episodes, r.env_steps, round(r.wall_time_s),
                 *(r.train.get(k) for k in train), *(r.greedy.get(k) for k in greedy),
                 *(r.random.get(k) for k in random)]
        lines.append("| " + " | ".join(map(_cell, cells)) + " |")
    groups: dict[tuple[Any, ...], list[TrialResult]] = {}
    for r in results:
        groups.setdefault(r.group(), []).append(r)
    if any(len(members) > 1 for members in groups.values()):
        lines += ["", f"By parameters, over the seeds: greedy {greedy_key} mean (min-max).", "",
                  "| " + " | ".join([*params, "seeds", f"greedy {greedy_key}", f"training {greedy_key}"]) + " |",
                  "|" + "---|" * len(params) + "---|---:|---:|"]
        for key, members in groups.items():
            values = [float(v) for r in members if (v := r.greedy.get(greedy_key)) is not None]
            trained = [float(v) for r in members if (v := r.train.get(greedy_key)) is not None]
            lines.append("| " + " | ".join([*map(_cell, key), ",".join(str(r.seed) for r in members),
                                            _stats(values), _stats(trained)]) + " |")
    return "\n".join(lines) + "\n"


def table_csv(results: Sequence[TrialResult]) -> str:
    params, train, greedy, random = _columns(results)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["trial", "seed", *params, "episodes", "env_steps", "wall_time_s", *(f"train_{k}" for k in train),
                     *(f"greedy_{k}" for k in greedy), *(f"random_{k}" for k in random)])
    for r in results:
        writer.writerow([r.name, r.seed, *(r.params.get(k, "") for k in params), r.episodes, r.env_steps,
                         r.wall_time_s, *(_csv(r.train.get(k)) for k in train),
                         *(_csv(r.greedy.get(k)) for k in greedy), *(_csv(r.random.get(k)) for k in random)])
    return buf.getvalue()


def _csv(value: Any) -> Any:
    return "" if value is None else value


def write_table(results: Sequence[TrialResult], title: str, greedy_key: str, markdown: Path, csv_path: Path) -> str:
    """Write both tables atomically; returns the markdown."""
    text = table_markdown(results, title, greedy_key)
    write_text_atomic(markdown, text)
    write_text_atomic(csv_path, table_csv(results))
    return text


def plot_curves(results: Sequence[TrialResult], metric: str, title: str, path: Path) -> None:
    """Every trial's `metric` per episode (moving average), thin, and each combination's mean over its seeds,
    thick, in the combination's colour."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups: dict[tuple[Any, ...], list[TrialResult]] = {}
    for r in results:
        groups.setdefault(r.group(), []).append(r)
    fig, ax = plt.subplots(figsize=(9, 5))
    try:
        for index, (key, members) in enumerate(groups.items()):
            colour = f"C{index % 10}"
            curves = [moving_average(r.curve) for r in members if r.curve]
            for curve in curves:
                ax.plot(np.arange(1, len(curve) + 1), curve, "-", color=colour, alpha=0.3, linewidth=0.8)
            if curves:
                length = min(len(c) for c in curves)
                label = ", ".join(f"{k}={v}" for k, v in zip(members[0].params, key)) or "every trial"
                ax.plot(np.arange(1, length + 1), np.mean([c[:length] for c in curves], axis=0), "-", color=colour,
                        linewidth=2.2, label=f"{label}: mean of {len(curves)}")
        ax.set_xlabel("episode")
        ax.set_ylabel(f"{metric} (moving average of {MOVING_AVERAGE} episodes)")
        ax.set_title(title, fontsize="medium")
        ax.grid(True, alpha=0.3)
        if groups:
            ax.legend(loc="best", fontsize="small")
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100)
    finally:
        plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())
