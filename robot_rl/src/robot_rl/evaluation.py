"""Evaluate a trained run: its greedy policy, then a uniformly random one, on the run's own task.

  evaluate.py --qtable RUN [--episodes N] [--horizon-s S] [--backend direct|ros] [--seed S]

RUN is a run folder (training_results/<task>/<run>, or its `latest` link) or its qtable.json; the
checkpoint names the task, the run's params.yaml gives its parameters. Each episode lasts until the
task terminates it or `--horizon-s` seconds of sim time have passed (default: the task's). The last
output line is one JSON object: {"task", "episodes", "horizon_s", "seed", "greedy": {...}, "random":
{...}}, each policy with mean_return and the task's metrics (`mean_<metric>`, `<metric>_rate`).
The direct backend (default) needs nothing running; `--backend ros` needs the task's sim node.
Every robot package's evaluate.py is this, for its own tasks.
"""
from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from pybullet_sim.client import SimConnectionError

from .params import ParamError
from .qlearn import QLearn
from .results import RunDirectory, aggregate
from .task import Episode, StateKey, TaskSpec, find_task, make_env


class TrainedRun:
    """A run's task, params, Q-table and state key, checked against each other."""

    def __init__(self, path: Path, tasks: Sequence[TaskSpec[Any]]):
        qtable = path / "qtable.json" if path.is_dir() else path
        checkpoint = RunDirectory(qtable.parent).load_checkpoint()
        try:
            self.task = find_task(list(tasks), checkpoint["task"])
            self.qlearn = QLearn.from_dict(checkpoint["qlearn"])
            saved_key = checkpoint["state_key"]
        except (KeyError, TypeError) as error:
            raise ValueError(f"{qtable}: not a training checkpoint (missing {error})") from None
        params_file = qtable.with_name("params.yaml")
        try:
            document = yaml.safe_load(params_file.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as error:
            raise ValueError(f"{params_file}: {error}") from None
        self.params = self.task.params_type.from_mapping(document or {}, str(params_file))
        self.state_key: StateKey = self.task.state_key(self.params)
        if self.state_key.to_dict() != saved_key:
            raise ValueError(f"{qtable}: the Q-table was trained with another state key than this code makes from "
                             f"{params_file}")


def run_episodes(env: Any, policy: Callable[[np.ndarray], int], episodes: int, task: TaskSpec[Any],
                 running_step: float) -> dict[str, float | None]:
    """Mean return and the task's metrics of `episodes` episodes of `policy`."""
    returns: list[float] = []
    metrics: dict[str, list[Any]] = {name: [] for name in task.metric_names}
    for _ in range(episodes):
        observation, _ = env.reset()
        total, steps, info, terminated = 0.0, 0, {}, False
        while True:
            observation, reward, terminated, truncated, info = env.step(policy(observation))
            total += reward
            steps += 1
            if terminated or truncated:
                break
        returns.append(total)
        episode = Episode(steps=steps, return_=total, terminated=terminated, duration=steps * running_step, info=info)
        for name, value in task.metrics(episode).items():
            metrics[name].append(value)
    return {**aggregate({"return": returns}), **aggregate(metrics)}


def evaluate(run: TrainedRun, episodes: int, horizon_s: float, backend: str, seed: int) -> dict[str, Any]:
    """Greedy, then seeded uniformly random, `episodes` each, from a seeded first reset."""
    steps = max(1, round(horizon_s / run.params.running_step))
    env = make_env(run.task, params=run.params, backend=backend, seed=seed, max_episode_steps=steps)
    run.qlearn.rng.seed(seed)
    rng = np.random.default_rng(seed)
    n_actions = int(env.action_space.n)  # type: ignore[attr-defined]
    try:
        env.reset(seed=seed)
        greedy = run_episodes(env, lambda obs: run.qlearn.greedy_action(run.state_key.key(obs)), episodes,
                              run.task, run.params.running_step)
        random_policy = run_episodes(env, lambda obs: int(rng.integers(n_actions)), episodes, run.task,
                                     run.params.running_step)
    finally:
        env.close()
    return {"task": run.task.env_id, "episodes": episodes, "horizon_s": steps * run.params.running_step,
            "seed": seed, "greedy": greedy, "random": random_policy}


def main(argv: Sequence[str], tasks: Sequence[TaskSpec[Any]], node_name: str) -> int:
    parser = argparse.ArgumentParser(prog="evaluate.py", description=__doc__.splitlines()[0])
    parser.add_argument("--qtable", required=True, type=Path, help="a run folder or its qtable.json")
    parser.add_argument("--episodes", type=int, default=20, help="episodes per policy (default 20)")
    parser.add_argument("--horizon-s", type=float, help="sim seconds per episode at most (default: the task's)")
    parser.add_argument("--backend", choices=("direct", "ros"), default="direct",
                        help="direct: an in-process sim (default); ros: the running sim node")
    parser.add_argument("--seed", type=int, default=0, help="seeds the sim, the random policy and tie breaks")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    if args.horizon_s is not None and not args.horizon_s > 0.0:
        parser.error("--horizon-s must be > 0")
    try:
        run = TrainedRun(args.qtable, tasks)
    except (OSError, ParamError, ValueError) as error:
        parser.exit(2, f"evaluate.py: cannot read the trained Q-table {args.qtable}: {error}\n")
    if args.backend == "ros":
        from .backends import init_ros_node
        try:
            init_ros_node(node_name)
        except SimConnectionError as error:
            parser.exit(1, f"evaluate.py: {error}\n")
    horizon_s = args.horizon_s if args.horizon_s is not None else run.task.eval_horizon_s
    try:
        report = evaluate(run, args.episodes, horizon_s, args.backend, args.seed)
    except SimConnectionError as error:
        parser.exit(1, f"evaluate.py: {error}\n")
    print(json.dumps(report))
    return 0
