"""Write docs/reference/tasks.md, the tasks' reference, from the registered task specs and their env modules.

As gymnasium generates its environment pages from the envs' docstrings, the page is generated, never
edited: per task, its spec (env id, task name, package, config, max_episode_steps, results folder,
reward topics, metrics), its env module's docstring (actions, observation, reward terms,
termination) and its parameters with their ranges, docs and the values of its YAML. After changing
any of those, run `./ws exec rosrun workspace_tools write_tasks_doc.py`; `--check` only compares,
and test/unit/test_tasks_doc.py fails while the page differs.
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import inspect
import os
import sys
import typing
from pathlib import Path
from typing import Any

from robot_rl import TASKS, Params, TaskSpec, package_path
from workspace_tools.robots import ROBOTS

REGENERATE = "./ws exec rosrun workspace_tools write_tasks_doc.py"
PAGE = Path("docs", "reference", "tasks.md")  # the page, relative to the repository
TRAINING_PACKAGES = tuple(importlib.import_module(robot.package) for robot in ROBOTS.values())


def registered_tasks() -> list[TaskSpec[Any]]:
    """Every task, in the order its package lists it, as registered in robot_rl.task.TASKS."""
    return [TASKS[spec.env_id] for package in TRAINING_PACKAGES for spec in package.TASKS]


def link(path: Path, repo: Path) -> str:
    """`path` as a link from the page's folder when it is inside the repository, else as code."""
    path = path.resolve()
    if not path.is_relative_to(repo):
        return f"`{path}`"
    return f"[`{path.relative_to(repo)}`]({Path(os.path.relpath(path, repo / PAGE.parent)).as_posix()})"


def cell(text: str) -> str:
    """Text for a table cell: a `|` would end the cell."""
    return text.replace("|", "\\|")


def value_text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, Params):
        return ", ".join(f"{name} {value_text(item)}" for name, item in dataclasses.asdict(value).items())  # type: ignore[call-overload]
    return str(value)


def parameter_rows(spec: TaskSpec[Any]) -> list[str]:
    """One table row per parameter of the task's params dataclass: key, value in its YAML, range, meaning."""
    params = spec.default_params()
    hints = typing.get_type_hints(spec.params_type)
    rows = []
    for field in dataclasses.fields(spec.params_type):
        kind = hints[field.name]
        value_range, choices = field.metadata.get("range"), field.metadata.get("choices")
        if choices:
            allowed = "one of " + ", ".join(f"`{choice}`" for choice in choices)
        elif value_range is not None and (value_range.low is not None or value_range.high is not None):
            allowed = f"`{value_range}`"
        else:
            allowed = ""
        rows.append(f"| `{field.name}` | {kind.__name__} | {value_text(getattr(params, field.name))} | {allowed} | "
                    f"{cell(field.metadata.get('doc', ''))} |")
    return rows


def task_section(spec: TaskSpec[Any], repo: Path) -> list[str]:
    module_name, class_name = spec.entry_point.split(":")
    module = importlib.import_module(module_name)
    docstring = inspect.getdoc(module) or ""
    summary, _, details = docstring.partition("\n\n")
    summary = " ".join(summary.split()).removeprefix(f"{spec.env_id}: ")
    metrics = ", ".join(f"`{name}`" for name in spec.metric_names)
    step_reward = "the sum so far, each step" if spec.publish_cumulated_reward else "each step's"
    return [
        f"## {spec.env_id}",
        "",
        summary[:1].upper() + summary[1:],
        "",
        "| | |",
        "|---|---|",
        f"| env id | `{spec.env_id}`, `gymnasium.make(\"{spec.env_id}\", backend=\"ros\" \\| \"direct\")` |",
        f"| task | `{spec.name}` (`roslaunch {spec.package} main.launch task:={spec.name}`) |",
        f"| package | `{spec.package}` |",
        f"| config | {link(spec.config_path, repo)} |",
        f"| max_episode_steps | {spec.max_episode_steps} |",
        f"| env class | `{class_name}` in {link(Path(inspect.getfile(module)), repo)} |",
        f"| robot | {link(spec.robot.urdf_path, repo)}, {link(spec.robot.sim_config_path, repo)} |",
        f"| results | `training_results/{spec.results_name}/` |",
        f"| reward topics | `{spec.reward_topic}` ({step_reward}), `{spec.episode_reward_topic}` |",
        f"| metrics | {metrics}; headline (progress line): `{spec.headline_metric}` |",
        f"| evaluation horizon | {spec.eval_horizon_s:g} s of sim time (`evaluate.py --horizon-s`) |",
        "",
        "```text",
        *details.splitlines(),
        "```",
        "",
        f"Parameters (`{spec.params_type.__name__}`; values from `config/{spec.name}.yaml`):",
        "",
        "| key | type | value | allowed | meaning |",
        "|---|---|---|---|---|",
        *parameter_rows(spec),
        "",
    ]


def render(repo: Path) -> str:
    """The whole page; `repo` is the repository root (links are relative to the page's folder)."""
    repo = repo.resolve()
    tasks = registered_tasks()
    lines = [
        "<!-- Generated by workspace_tools/scripts/write_tasks_doc.py from the task specs, their params and "
        f"their env modules' docstrings. Do not edit: run `{REGENERATE}`. -->",
        "",
        "# Tasks",
        "",
        "Every task is a gymnasium 1.x env, registered when its package is imported "
        "(`import moving_cube_training, hopper_training`), with its `TaskSpec` (`robot_rl.task`). "
        "Each reward term is in `info` as `reward_<term>`, and the terms sum to the reward.",
        "",
        "| env id | task | package | max_episode_steps | headline metric |",
        "|---|---|---|---:|---|",
        *(f"| [`{spec.env_id}`](#{spec.env_id.lower()}) | `{spec.name}` | "
          f"`{spec.package}` | {spec.max_episode_steps} | `{spec.headline_metric}` |" for spec in tasks),
        "",
    ]
    for spec in tasks:
        lines += task_section(spec, repo)
    return "\n".join(lines).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    repo = package_path("workspace_tools").parent
    default = repo / PAGE
    parser.add_argument("--output", type=Path, default=default, help=f"the page to write (default: {default})")
    parser.add_argument("--check", action="store_true", help="only compare; exit 1 when the page differs")
    args = parser.parse_args(argv)
    page = render(repo)
    current = args.output.read_text() if args.output.is_file() else None
    if args.check:
        if current != page:
            print(f"{args.output} is out of date: run {REGENERATE}", file=sys.stderr)
            return 1
        return 0
    if current != page:
        args.output.write_text(page)
        print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
