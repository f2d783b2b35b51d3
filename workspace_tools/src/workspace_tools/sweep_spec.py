"""What a sweep is made of: the grammar of `./ws sweep`'s arguments, its trials and their names (no Ray here).

  ./ws sweep [ROBOT] [task:=T] [agent:=A] [seeds:=0-9] [NAME:=v1,v2 ...] [max_steps:=N] [name:=SWEEP]
             [resume:=true] [cluster:=ADDRESS] [concurrent:=N] [max_failures:=N] [eval_episodes:=N]
             [eval_seed:=S] [results_dir:=DIR]

`seeds:=` takes seeds and inclusive ranges separated by commas (`0-9`, `0,3,5`, `0-2,7`); default: the
task config's seed. Any other NAME is a training parameter of the task (a field of its params dataclass,
robot_rl.params) or, for a deep agent, one of the agent's own params (robot_rl.deep's DqnParams, ...),
with one value or several separated by commas; each value is checked as the task's YAML (or the agent's)
is, and every combination too. A name that is both a task's and the agent's parameter is refused. An
agent parameter goes into the trial's agent config: the agent's default file for the task
(AgentSpec.config_for) with the trial's values in it. `max_steps:=N` (deep agents) is every trial's
budget of env steps, as `./ws run ... max_steps:=N`; the task's nepisodes then no longer bounds it
unless `nepisodes:=` is given too. The trials are every seed times every combination, in that order; a
trial's name is `seed=S` followed by `NAME=VALUE` of each parameter given more than one value, e.g.
`seed=3,alpha=0.2` (characters other than letters, digits and `._+=,-` become `_`). Anything wrong gives
one line (SweepError) naming the argument.
"""
from __future__ import annotations

import dataclasses
import importlib
import itertools
import math
import re
import typing
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from robot_rl import (
    DEFAULT_AGENT,
    MAX_COUNT,
    MAX_SEED,
    AgentSpec,
    ParamError,
    Params,
    TaskSpec,
    find_agent,
    find_task,
    load_yaml_file,
    make_env,
    parse_scalar,
)
from workspace_tools.robots import DEFAULT_ROBOT, ROBOTS

# The arguments that say how a sweep runs, not which trials it has: a resumed sweep may change them.
RUN_OPTIONS = ("name", "resume", "cluster", "concurrent", "results_dir")
OPTIONS = (*RUN_OPTIONS, "task", "agent", "seeds", "max_steps", "max_failures", "eval_episodes", "eval_seed")
SWEEP_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")
UNSAFE = re.compile(r"[^A-Za-z0-9._+=,-]")
SCALARS = (bool, int, float, str)
EXPONENT = re.compile(r"[-+]?\d+(\.\d*)?[eE][-+]?\d+")
MAX_TRIALS = 1000  # trials in one sweep at most: each is a whole training run


class SweepError(ValueError):
    """A sweep argument that cannot be used; str() is one line naming it."""


@dataclass(frozen=True)
class Trial:
    """One training run of a sweep: its name, its seed and every parameter the sweep sets besides the seed (the
    task's in `changes`, the agent's in `agent_changes`)."""

    name: str
    seed: int
    changes: dict[str, Any] = field(default_factory=dict)
    agent_changes: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SweepSpec:
    robot: str
    package: str
    task: TaskSpec[Any]
    agent: AgentSpec
    seeds: tuple[int, ...]
    grid: tuple[tuple[str, tuple[Any, ...]], ...]  # (parameter, its values) in the order given
    grid_args: tuple[str, ...]                      # the arguments that define the trials, as given
    agent_grid: tuple[str, ...] = ()                # the grid's parameters that are the agent's, not the task's
    max_steps: int = 0                              # a deep agent's env step budget; 0: nepisodes decides
    name: str = ""                                  # empty: the driver names the sweep by the UTC time
    resume: bool = False
    cluster: str = ""                               # empty: a local Ray on this machine
    concurrent: int = 0                             # trials at once; 0: one per CPU of the Ray cluster
    max_failures: int = 2
    eval_episodes: int = 20
    eval_seed: int = 0
    results_dir: str = "training_results"

    @property
    def varied(self) -> tuple[str, ...]:
        """The parameters given more than one value (they name the trials)."""
        return tuple(name for name, values in self.grid if len(values) > 1)

    def trials(self) -> list[Trial]:
        """Every seed times every combination of the grid, each combination checked as a whole."""
        defaults = self.task.default_params()
        agent_defaults = agent_default_params(self.agent, self.task) if self.agent_grid else None
        names = [name for name, _ in self.grid]
        trials = []
        for seed in self.seeds:
            for combination in itertools.product(*(values for _, values in self.grid)):
                values = dict(zip(names, combination))
                label = ", ".join(f"{k}:={format_value(v)}" for k, v in values.items()) or f"seeds:={seed}"
                changes = {k: v for k, v in values.items() if k not in self.agent_grid}
                agent_changes = {k: v for k, v in values.items() if k in self.agent_grid}
                try:
                    defaults.with_changes(label, seed=seed, **changes)
                    if agent_defaults is not None:
                        agent_defaults.with_changes(label, **agent_changes)
                except ParamError as error:
                    raise SweepError(str(error)) from None
                trials.append(Trial(trial_name(seed, {k: values[k] for k in self.varied}), seed, changes,
                                    agent_changes))
        return trials


def format_value(value: Any) -> str:
    """A parameter value as the arguments write it (true/false, 0.2, 1e-05, words)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def trial_name(seed: int, varied: dict[str, Any]) -> str:
    """`seed=S,NAME=VALUE,...`: readable and safe as a folder name."""
    parts = [f"seed={seed}", *(f"{name}={format_value(value)}" for name, value in varied.items())]
    return UNSAFE.sub("_", ",".join(parts))


def parse_seeds(text: str) -> tuple[int, ...]:
    """`0-9`, `0,3,5`, `0-2,7`: the seeds, in order, each once."""
    seeds: list[int] = []
    for item in text.split(","):
        match = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", item)
        if not match:
            raise SweepError(f"seeds:={text}: {item.strip()!r} is not a seed or a range FIRST-LAST of seeds "
                             f"(e.g. seeds:=0-9 or seeds:=0,3,5)")
        first, last = int(match[1]), int(match[2] if match[2] is not None else match[1])
        if last < first:
            raise SweepError(f"seeds:={text}: the range {item.strip()} ends before it starts")
        if last > MAX_SEED:
            raise SweepError(f"seeds:={text}: seeds go from 0 to {MAX_SEED}")
        if len(seeds) + last - first + 1 > MAX_TRIALS:
            raise SweepError(f"seeds:={text}: more than {MAX_TRIALS} seeds, a sweep's most trials (each is a whole "
                             f"training run)")
        seeds.extend(range(first, last + 1))
    seen: set[int] = set()
    for seed in seeds:
        if seed in seen:
            raise SweepError(f"seeds:={text}: seed {seed} is given twice")
        seen.add(seed)
    return tuple(seeds)


def _scalar_fields(params_type: Any) -> tuple[str, ...]:
    """The names of a params dataclass's fields of a plain type (bool, int, float, str)."""
    hints = typing.get_type_hints(params_type)
    return tuple(f.name for f in dataclasses.fields(params_type) if hints[f.name] in SCALARS)


def sweepable_params(task: TaskSpec[Any]) -> tuple[str, ...]:
    """The task's training parameters a sweep can set: its params dataclass's plain fields (not seed)."""
    return tuple(name for name in _scalar_fields(task.params_type) if name != "seed")


def agent_default_params(agent: AgentSpec, task: TaskSpec[Any]) -> Params:
    """The agent's params for `task`, from its default file for the task (AgentSpec.config_for)."""
    params = agent.load_params(agent.config_for(task))
    assert params is not None, f"agent {agent.name} has no params of its own"
    return params


def agent_sweepable_params(agent: AgentSpec, task: TaskSpec[Any]) -> tuple[str, ...]:
    """The agent's own params a sweep can set (none for an agent whose params are the task's)."""
    return () if agent.params is None else _scalar_fields(type(agent_default_params(agent, task)))


def _sweep_scalar(text: str) -> Any:
    """A value as YAML types it, and a number in exponent form without a dot (1e-4, which YAML 1.1 leaves a
    string) a float, as roslaunch types it."""
    value = parse_scalar(text)
    return float(value) if isinstance(value, str) and EXPONENT.fullmatch(value) else value


def parse_values(name: str, text: str, defaults: Params) -> tuple[Any, ...]:
    """The values of `name:=text` (comma-separated), each checked as the task's (or agent's) YAML is."""
    values = []
    for item in text.split(","):
        if not item.strip():
            raise SweepError(f"{name}:={text}: an empty value (write the values separated by commas, e.g. "
                             f"{name}:=0.1,0.2)")
        try:
            checked = defaults.with_changes(f"{name}:={text}", **{name: _sweep_scalar(item.strip())})
        except ParamError as error:
            raise SweepError(str(error)) from None
        value = getattr(checked, name)
        if value in values:
            raise SweepError(f"{name}:={text}: the value {format_value(value)} is given twice")
        values.append(value)
    return tuple(values)


def _integer(name: str, text: str, low: int) -> int:
    value = parse_scalar(text)
    if not isinstance(value, int) or isinstance(value, bool) or value < low:
        raise SweepError(f"{name}:={text}: expected a whole number >= {low}")
    return value


def parse_sweep(argv: Sequence[str]) -> SweepSpec:
    """The sweep `argv` (the arguments of ./ws sweep) asks for; SweepError names what is wrong."""
    args = list(argv)
    robot = args.pop(0) if args and ":=" not in args[0] else DEFAULT_ROBOT
    if robot not in ROBOTS:
        raise SweepError(f"unknown robot {robot!r} (known: {', '.join(ROBOTS)})")
    package = ROBOTS[robot].package
    given: dict[str, str] = {}
    for arg in args:
        name, sep, value = arg.partition(":=")
        if not sep or not name:
            raise SweepError(f"{arg!r} is not an argument NAME:=VALUE (see ./ws sweep --help)")
        if name in given:
            raise SweepError(f"{name}:= is given twice")
        given[name] = value
    tasks = list(importlib.import_module(package).TASKS)
    try:
        task = find_task(tasks, given.get("task", tasks[0].name))
        agent = find_agent(given.get("agent", DEFAULT_AGENT))
    except ParamError as error:
        raise SweepError(str(error)) from None
    defaults = task.default_params()
    known, agent_known = sweepable_params(task), agent_sweepable_params(agent, task)
    grid, agent_grid = [], []
    for name, text in given.items():
        if name in OPTIONS:
            continue
        if name == "seed":
            raise SweepError("seed:= is not a sweep argument: give the seeds with seeds:= (e.g. seeds:=0-4)")
        if name in known and name in agent_known:
            raise SweepError(f"{name}:= is ambiguous: both a training parameter of task {task.name} and one of agent "
                             f"{agent.name}'s; sweep it in a copy of one of their YAML files instead")
        if name in agent_known:
            grid.append((name, parse_values(name, text, agent_default_params(agent, task))))
            agent_grid.append(name)
            continue
        if name not in known:
            agent_names = f", agent {agent.name}'s: {', '.join(agent_known)}" if agent_known else ""
            raise SweepError(f"unknown parameter {name!r}: not a training parameter of task {task.name} "
                             f"(known: {', '.join(known)}{agent_names}) nor a sweep argument ({', '.join(OPTIONS)})")
        grid.append((name, parse_values(name, text, defaults)))
    max_steps = _integer("max_steps", given["max_steps"], 1) if "max_steps" in given else 0
    if max_steps > MAX_COUNT:
        raise SweepError(f"max_steps:={given['max_steps']}: at most {MAX_COUNT}")
    if max_steps and agent.params is None:
        raise SweepError(f"max_steps:= is a deep agent's budget of env steps; agent {agent.name} trains the task's "
                         f"nepisodes (give nepisodes:= instead)")
    name = given.get("name", "")
    if name and not SWEEP_NAME.fullmatch(name):
        raise SweepError(f"name:={name}: a sweep's name is letters, digits and ._- (not starting with . or -)")
    resume = parse_scalar(given.get("resume", "false"))
    if not isinstance(resume, bool):
        raise SweepError(f"resume:={given['resume']}: expected true or false")
    spec = SweepSpec(
        robot=robot, package=package, task=task, agent=agent,
        seeds=parse_seeds(given["seeds"]) if "seeds" in given else (defaults.seed,), grid=tuple(grid),
        grid_args=(robot, *(arg for arg in args if arg.partition(":=")[0] not in RUN_OPTIONS)),
        agent_grid=tuple(agent_grid), max_steps=max_steps, name=name, resume=resume, cluster=given.get("cluster", ""),
        concurrent=_integer("concurrent", given["concurrent"], 1) if "concurrent" in given else 0,
        max_failures=_integer("max_failures", given.get("max_failures", "2"), 0),
        eval_episodes=_integer("eval_episodes", given.get("eval_episodes", "20"), 1),
        eval_seed=_integer("eval_seed", given.get("eval_seed", "0"), 0),
        results_dir=given.get("results_dir", "training_results"))
    count = len(spec.seeds) * math.prod(len(values) for _, values in spec.grid)
    if count > MAX_TRIALS:
        raise SweepError(f"{count} trials ({len(spec.seeds)} seeds x "
                         f"{' x '.join(f'{len(v)} {k}' for k, v in spec.grid if len(v) > 1) or '1'}): a sweep has at "
                         f"most {MAX_TRIALS} trials (each is a whole training run)")
    spec.trials()  # every combination checked now, before anything runs
    return spec


def check_agent_fits(spec: SweepSpec, trials: Sequence[Trial]) -> None:
    """SweepError in one line when the agent cannot train a trial's env (its actions' kind, a buffer beyond the
    memory): the env of each distinct set of the trials' task params is made in-process to ask (AgentSpec.check_fit,
    as the training node asks before its run folder)."""
    defaults = spec.task.default_params()
    agent_defaults = agent_default_params(spec.agent, spec.task) if spec.agent.params is not None else None
    source = f"agent {spec.agent.name} on {spec.task.env_id}"
    checked: set[tuple[str, str]] = set()
    for trial in trials:
        key = (repr(sorted(trial.changes.items())), repr(sorted(trial.agent_changes.items())))
        if key in checked:
            continue
        checked.add(key)
        try:
            params = defaults.with_changes(trial.name, **trial.changes)
            agent_params = None if agent_defaults is None else agent_defaults.with_changes(trial.name,
                                                                                           **trial.agent_changes)
            env = make_env(spec.task, params=params, backend="direct")
            try:
                spec.agent.check_fit(env, agent_params, source)
            finally:
                env.close()
        except (ParamError, ValueError) as error:  # ValueError: params the env refuses
            raise SweepError(str(error)) from None


def trial_config(task: TaskSpec[Any], trial: Trial, max_steps: int = 0) -> dict[str, Any]:
    """The task's default YAML document with the trial's seed and parameters in it (a config:= for main.launch).
    With a budget of `max_steps` env steps the episodes do not bound the run (unless the trial sets nepisodes)."""
    document = load_yaml_file(task.config_path)
    target = document
    for part in task.params_namespace.strip("/").split("/"):
        if part:
            target = target[part]
    if max_steps:
        target["nepisodes"] = MAX_COUNT
    target.update(trial.changes, seed=trial.seed)
    return document


def trial_agent_config(agent: AgentSpec, task: TaskSpec[Any], trial: Trial) -> dict[str, Any] | None:
    """The agent's default YAML for the task with the trial's agent parameters in it (an agent_config:=); None when
    the agent has no params of its own."""
    path = agent.config_for(task)
    if path is None:
        return None
    document = load_yaml_file(path)
    document.update(trial.agent_changes)
    return document
