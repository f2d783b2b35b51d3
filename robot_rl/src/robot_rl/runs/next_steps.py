"""What a training node says around a run: the start line, the end block (the results folder, the headline
metric, the commands to evaluate, play and train further) and the line of a resume of a run already complete.

The commands are `./ws`'s when the node runs under `./ws run` (which sets $WS_RUN to "./ws run ROBOT"), else
plain rosrun/roslaunch's; paths are relative to the folder the command ran in (~launch_dir) when under it.
"""
from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

WS_RUN_VARIABLE = "WS_RUN"   # "./ws run ROBOT", set by ./ws run for its nodes
WS_RESULTS_VARIABLE = "WS_RUN_RESULTS"  # ./ws run's default results_dir, set by it for its nodes


@dataclass(frozen=True)
class RunContext:
    """Who trains what, where: enough to write the commands that come next."""

    package: str               # the robot's training package (evaluate.py's, main.launch's)
    task: str                  # task:= (given only when the package has more than one task)
    several_tasks: bool
    agent: str                 # agent:= (given unless the default)
    default_agent: str
    run_path: Path
    launch_dir: str = ""       # where the command ran: paths are shown relative to it when under it
    own_episodes: bool = False  # the agent trains its params' count of episodes (bc_dagger), not nepisodes
    given: tuple[str, ...] = ()  # the run's launch arguments ("config:=FILE", ...) a command to train it repeats

    def shown(self, path: Path) -> str:
        if self.launch_dir:
            try:
                return str(path.relative_to(self.launch_dir))
            except ValueError:
                pass
        return str(path)

    def _ws(self) -> str:
        return os.environ.get(WS_RUN_VARIABLE, "")

    def exec_prefix(self) -> str:
        return "./ws exec " if self._ws() else ""

    def train_command(self, *args: str) -> str:
        """The command that trains this run's task with this agent, its given launch arguments but those `args`
        name, and `args`."""
        base = self._ws() or f"roslaunch {self.package} main.launch"
        named = {arg.split(":=", 1)[0] for arg in args}
        words = [base, *([f"task:={self.task}"] if self.several_tasks else []),
                 *([f"agent:={self.agent}"] if self.agent != self.default_agent else []),
                 *(arg for arg in self.given if arg.split(":=", 1)[0] not in named), *args]
        return " ".join(words)

    def further_command(self, episodes: int, nepisodes: int = 0, max_steps: int = 0) -> str:
        """How to train this run's policy further: resume it with twice its episodes, or, for a run with a step
        budget (`max_steps`, its episode budget `nepisodes` kept), twice its env steps; for an agent whose params
        count its episodes, a new run with more in its params (a resume keeps the run's params)."""
        name = self.run_path.name
        if self.own_episodes:
            return (f"{self.train_command('agent_config:=FILE')} (a new run: agent {self.agent} trains the episodes "
                    f"its params count, not nepisodes:=, and a resume keeps the run's params)")
        if max_steps:
            return self.train_command("resume:=true", f"run:={name}", f"nepisodes:={max(nepisodes, episodes)}",
                                      f"max_steps:={2 * max_steps}")
        return self.train_command("resume:=true", f"run:={name}", f"nepisodes:={2 * episodes}")

    def play_command(self) -> str:
        """One greedy episode into a video: ./ws demo's (into demos/), or evaluate.py's (into the run folder)."""
        if self._ws():
            return f"{self._ws().replace('./ws run', './ws demo', 1)} run:={self.shown(self.run_path)}"
        return self.evaluate_command("--episodes", "1", "--video", self.shown(self.run_path / "greedy.mp4"))

    def evaluate_command(self, *args: str) -> str:
        return f"{self.exec_prefix()}rosrun {self.package} evaluate.py --run {self.shown(self.run_path)}" + \
            "".join(f" {arg}" for arg in args)


def start_line(context: RunContext, env_id: str, nepisodes: int, max_steps: int, resumed_from: int | None,
               quiet: bool) -> str:
    """The one line a run starts with (it begins "Results go to"); `nepisodes`: the run's budget (the task's, or the
    agent's params' count when context.own_episodes)."""
    budget = f"{nepisodes} episodes" + (f" or {max_steps} env steps, whichever comes first" if max_steps else "") + \
        (f" (as agent {context.agent}'s params count them; nepisodes is not used)" if context.own_episodes else "")
    what = f"resuming after episode {resumed_from}, up to {budget}" if resumed_from is not None else budget
    more = "; every episode's EP: line with quiet:=false" if quiet else ""
    return f"Results go to {context.shown(context.run_path)}: {env_id} with {context.agent}, {what}{more}"


def headline(summary: Mapping[str, Any]) -> str:
    """"success_rate 0.93 over the last 100 episodes" from summary.json's entries."""
    metric = summary.get("headline_metric", "")
    metrics = summary.get("metrics_last_100", {}) or {}
    for key in (f"{metric}_rate", f"mean_{metric}"):
        if key in metrics:
            value = metrics[key]
            shown = "n/a" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.3g}"
            return f"{key} {shown} over the last {min(int(summary.get('episodes', 0)), 100)} training episodes"
    return "no headline metric"


def end_block(context: RunContext, summary: Mapping[str, Any], video: Path | None) -> list[str]:
    """The lines a completed run ends with: where, how well, and what to run next."""
    episodes = int(summary["episodes"])
    play = context.play_command()
    lines = [f"Done: {context.shown(context.run_path)}/ ({episodes} episodes; learning_curve.png, summary.json)",
             f"  {headline(summary)} (exploring; evaluate.py measures the greedy policy)",
             f"  evaluate it:   {context.evaluate_command()}",
             f"  play it:       {play}" + (f" (or open {context.shown(video)}: its greedy episode)"
                                              if video is not None else ""),
             f"  train further: {_further(context, summary)}"]
    return lines


def complete_lines(context: RunContext, summary: Mapping[str, Any]) -> list[str]:
    """What a resume of a run that is complete says instead of training (nothing is left to train)."""
    episodes = int(summary["episodes"])
    further = "train a new run with more" if context.own_episodes else "give more episodes"
    return [f"Run {context.shown(context.run_path)} is complete ({episodes} of {summary.get('nepisodes', episodes)} "
            f"episodes): nothing to resume. To train it further, {further}: {_further(context, summary)}",
            f"  evaluate it:   {context.evaluate_command()}"]


def _further(context: RunContext, summary: Mapping[str, Any]) -> str:
    """context.further_command for the run `summary` describes (its episodes, and its budgets)."""
    return context.further_command(int(summary["episodes"]), int(summary.get("nepisodes") or 0),
                                   int(summary.get("max_steps") or 0))
