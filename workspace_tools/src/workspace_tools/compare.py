"""The course's comparison: every agent of robot_rl.agents on one task, at the same number of env steps.

  compare_agents.py ROBOT [--task TASK] [--seeds 0 1 2] [--nepisodes N] [--eval-seed 0] [--episodes 20]
                    [--output DIR]

For each seed (the task's `seed` param: Q-learning's RNG, SB3's seed; the sim's noise seed too), over
ROS with one env, as `./ws run ROBOT task:=TASK agent:=...` trains: the first agent (tabular Q-learning)
for the task config's nepisodes (or --nepisodes); then the others that can act in the task's action
space (DQN and PPO on Discrete actions; PPO and SAC on Box; not rllib_ppo, whose runners need Ray) with
max_steps:= the env steps that first run took, so all of them see the same number of env steps. Each deep agent's
params are its default file for the task (the task's own config/agents/<task>.<agent>.yaml if there is one:
AgentSpec.config_for), recorded per run in the JSON and named in the table. Every final policy is evaluated
greedily (evaluate.py, --episodes episodes, direct backend, seed --eval-seed). Writes
DIR/comparison.json (every run), DIR/comparison.md (the table: the headline metric of the greedy
policy, wall time, env steps/s; mean and range over the seeds) and DIR/learning_curves.png (the
headline metric per episode, averaged over 50 episodes, against env steps; one line per agent, the
mean over the seeds, the band their range). The runs stay in
DIR/runs/ (training_results layout). Machine and date are in the JSON and the table.
"""
from __future__ import annotations

import argparse
import datetime
import importlib
import json
import statistics
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from robot_rl import AGENTS, AgentSpec, ParamError, RunDirectory, TaskSpec, find_task, make_env, moving_average
from workspace_tools.processes import Processes, RosMaster, launch_args
from workspace_tools.robots import ROBOTS

RUN_TIMEOUT = 4 * 3600.0


def _log(message: str) -> None:
    print(f"[compare] {message}", file=sys.stderr, flush=True)


def _config_with_seed(task: TaskSpec[Any], seed: int, folder: Path) -> Path:
    """The task's config with its `seed` changed, as a YAML file for config:=."""
    document = yaml.safe_load(task.config_path.read_text())
    target = document
    for part in task.params_namespace.strip("/").split("/"):
        if part:
            target = target[part]
    target["seed"] = seed
    path = folder / f"{task.name}-seed{seed}.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


def _task(robot: str, name: str | None) -> TaskSpec[Any]:
    """The robot's task called `name` (default: its package's first, as ./ws run's)."""
    tasks = list(importlib.import_module(ROBOTS[robot].package).TASKS)
    return find_task(tasks, name or tasks[0].name)


def _agents(task: TaskSpec[Any]) -> list[AgentSpec]:
    """The agents that can act in the task's action space (DQN: Discrete; SAC: Box), tabular Q-learning first."""
    env = make_env(task, backend="direct")
    try:
        space = env.action_space
    finally:
        env.close()
    agents = []
    for agent in AGENTS.values():
        if agent.needs_ray:  # the distributed engine (rllib_ppo) is compared by ./ws bench --sections rllib
            _log(f"{agent.name} left out: it trains on Ray's env runners, not on the one env over ROS compared here")
            continue
        params = agent.load_params(agent.config_for(task))
        try:
            if params is not None:
                params.check_action_space(space, f"agent {agent.name}")  # type: ignore[attr-defined]
        except ParamError as error:
            _log(f"{agent.name} left out: {error}")
            continue
        agents.append(agent)
    return agents


def _train(robot: str, task: TaskSpec[Any], agent: AgentSpec, seed: int, config: Path, results: Path,
           log_dir: Path, max_steps: int | None, nepisodes: int | None) -> Path:
    """One training run over ROS (the robot's main.launch); returns its run folder."""
    package = ROBOTS[robot].package
    args: dict[str, Any] = dict(config=config, results_dir=results, seed=seed, video="false", quiet="true",
                                agent=agent.name)
    if ROBOTS[robot].task_arg:
        args.update(task=task.name)
    if nepisodes is not None:
        args.update(nepisodes=nepisodes)
    if max_steps is not None:
        args.update(max_steps=max_steps, nepisodes=10**6)  # the step budget decides
    master = RosMaster(log_dir)
    try:
        result = master.run(["rosrun", "workspace_tools", "roslaunch_checked.py", package, "main.launch",
                             *launch_args(**args)], timeout=RUN_TIMEOUT)
    finally:
        master.close()
    if result.returncode != 0:
        raise RuntimeError(f"{robot} {agent.name} seed {seed} failed:\n{result.stdout[-3000:]}\n"
                           f"{result.stderr[-2000:]}")
    return (results / agent.results_name(task) / "latest").resolve()


def _evaluate(robot: str, run: Path, episodes: int, seed: int, log_dir: Path) -> dict[str, Any]:
    package = ROBOTS[robot].package
    runner = Processes(log_dir)
    try:
        result = runner.run(["rosrun", package, "evaluate.py", "--run", str(run), "--episodes", str(episodes),
                             "--seed", str(seed), "--backend", "direct"], timeout=3600)
    finally:
        runner.close()
    if result.returncode != 0:
        raise RuntimeError(f"evaluate.py {run} failed:\n{result.stderr[-3000:]}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def _curve(run: Path, metric: str) -> tuple[list[float], list[float]]:
    """(cumulative env steps, the metric's moving average) per episode of a run."""
    records = RunDirectory(run).read_episodes()
    steps = np.cumsum([r.steps for r in records]).tolist()
    return steps, moving_average([float(r.metrics[metric]) for r in records]).tolist()


def _machine() -> str:
    import os
    import platform
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor())
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def compare(robot: str, task: TaskSpec[Any], seeds: list[int], eval_seed: int, episodes: int, output: Path,
            nepisodes: int | None) -> dict[str, Any]:
    output.mkdir(parents=True, exist_ok=True)
    agents = _agents(task)
    results = output / "runs"
    headline = task.headline_metric
    greedy_key = "success_rate" if headline == "success" else f"mean_{headline}"
    report: dict[str, Any] = {"robot": robot, "task": task.env_id, "machine": _machine(),
                              "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
                              "seeds": seeds, "eval_seed": eval_seed, "eval_episodes": episodes,
                              "qlearn_nepisodes": nepisodes or task.default_params().nepisodes,
                              "running_step": task.default_params().running_step,
                              "headline_metric": headline, "greedy_metric": greedy_key,
                              "agents": [agent.name for agent in agents], "runs": []}
    with tempfile.TemporaryDirectory(prefix="compare-") as tmp_dir:
        tmp = Path(tmp_dir)
        for seed in seeds:
            config = _config_with_seed(task, seed, output)
            budget = None
            for agent in agents:
                run = _train(robot, task, agent, seed, config, results, tmp / f"{agent.name}-{seed}", budget,
                             nepisodes)
                summary = json.loads((run / "summary.json").read_text())
                if budget is None:  # the first agent's run sets the others' step budget
                    budget = summary["env_steps"]
                evaluation = _evaluate(robot, run, episodes, eval_seed, tmp / f"eval-{agent.name}-{seed}")
                steps, curve = _curve(run, headline)
                entry = {"agent": agent.name, "agent_config": summary.get("agent_config"), "seed": seed,
                         "run": str(run), "env_steps": summary["env_steps"],
                         "episodes": summary["episodes"], "wall_time_s": summary["wall_time_s"],
                         "env_steps_per_s": summary["env_steps_per_s"], "greedy": evaluation["greedy"],
                         "random": evaluation["random"], "curve_steps": steps, "curve": curve}
                report["runs"].append(entry)
                _log(f"{robot} {agent.name} seed {seed}: {summary['env_steps']} env steps in "
                     f"{summary['wall_time_s']:.0f} s, greedy {greedy_key} {evaluation['greedy'][greedy_key]:.3g}")
                (output / "comparison.json").write_text(json.dumps(report, indent=1) + "\n")
    _write_table(report, output / "comparison.md")
    _plot(report, output / "learning_curves.png")
    return report


def _stats(values: list[float], fmt: str) -> str:
    mean = statistics.fmean(values)
    return fmt.format(mean) if len(values) == 1 else f"{fmt.format(mean)} ({fmt.format(min(values))}-" \
                                                     f"{fmt.format(max(values))})"


def _write_table(report: dict[str, Any], path: Path) -> None:
    key = report["greedy_metric"]
    lines = [f"{report['task']} (running_step {report['running_step']} s, tabular Q-learning "
             f"{report['qlearn_nepisodes']} episodes, the others its env steps), seeds "
             f"{', '.join(map(str, report['seeds']))} (mean (min-max)); greedy policy: "
             f"{report['eval_episodes']} episodes, direct backend, evaluation seed {report['eval_seed']}; "
             f"{report['machine']}, {report['date']}", "",
             f"| agent (params) | env steps | greedy {key} | random {key} | wall time (s) | env steps/s |",
             "|---|---:|---:|---:|---:|---:|"]
    for agent in report.get("agents", AGENTS):
        runs = [r for r in report["runs"] if r["agent"] == agent]
        if runs:
            configs = sorted({Path(r["agent_config"]).name for r in runs if r.get("agent_config")})
            lines.append(f"| {agent} ({', '.join(configs) or 'the task config'}) | "
                         f"{_stats([r['env_steps'] for r in runs], '{:.0f}')} | "
                         f"{_stats([r['greedy'][key] for r in runs], '{:.2f}')} | "
                         f"{_stats([r['random'][key] for r in runs], '{:.2f}')} | "
                         f"{_stats([r['wall_time_s'] for r in runs], '{:.0f}')} | "
                         f"{_stats([r['env_steps_per_s'] for r in runs], '{:.0f}')} |")
    path.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def _plot(report: dict[str, Any], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 4.5))
    try:
        agents = report.get("agents", list(AGENTS))
        for agent in agents:
            runs = [r for r in report["runs"] if r["agent"] == agent and r["curve_steps"]]
            if not runs:
                continue
            end = min(r["curve_steps"][-1] for r in runs)
            grid = np.linspace(0, end, 200)
            curves = np.array([np.interp(grid, r["curve_steps"], r["curve"]) for r in runs])
            ax.plot(grid, curves.mean(axis=0), label=agent)
            ax.fill_between(grid, curves.min(axis=0), curves.max(axis=0), alpha=0.2)
        ax.set_xlabel("env steps")
        ax.set_ylabel(f"{report['headline_metric']} (moving average of 50 episodes)")
        ax.set_title(f"{report['task']}: {', '.join(agents)} (seeds {', '.join(map(str, report['seeds']))})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best")
        fig.tight_layout()
        fig.savefig(path, dpi=100)
    finally:
        plt.close(fig)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("robot", choices=sorted(ROBOTS))
    parser.add_argument("--task", help="a task of the robot (default: its first, as ./ws run's)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--nepisodes", type=int, help="tabular Q-learning's episodes (default: the task config's)")
    parser.add_argument("--eval-seed", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=20, help="greedy (and random) evaluation episodes")
    parser.add_argument("--output", type=Path, help="default: comparison/<robot>")
    parser.add_argument("--table-only", action="store_true", help="rewrite the table and plot from comparison.json")
    args = parser.parse_args(argv)
    try:
        task = _task(args.robot, args.task)
    except ParamError as error:
        parser.error(str(error))
    output = args.output or Path("comparison") / (args.robot if args.task is None else f"{args.robot}-{task.name}")
    if args.table_only:
        report = json.loads((output / "comparison.json").read_text())
        _write_table(report, output / "comparison.md")
        _plot(report, output / "learning_curves.png")
        return 0
    compare(args.robot, task, args.seeds, args.eval_seed, args.episodes, output.resolve(), args.nepisodes)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
