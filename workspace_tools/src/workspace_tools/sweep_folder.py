"""A sweep's folder (workspace_tools.sweep): made whole or not at all, found by its name to resume, and held by one
driver at a time (its lock).

A new sweep is checked whole before its folder <results_dir>/<results name>/<SWEEP>/ is made (its trials; the agent
on each distinct env, sweep_spec.check_agent_fits), its name free under every results folder; a start that fails
after (a full disk, Ctrl-C) removes the folder. sweep.yaml is written last: a folder with it is a whole sweep.
`resume:=true name:=SWEEP` finds the one <results_dir>/*/<SWEEP>/sweep.yaml of its robot (and of task:= and
agent:= if given), whatever its task and agent. The driver holds the sweep's lock (flock on <sweep>/.lock) for its
life, as a training holds its run's: a second driver of the sweep stops with SweepLockedError.
"""
from __future__ import annotations

import dataclasses
import datetime
import shutil
from pathlib import Path
from typing import Any

import yaml

from robot_rl import hold_lock, write_text_atomic
from workspace_tools import sweep_spec
from workspace_tools.sweep_spec import SweepError, SweepSpec, Trial, check_agent_fits, parse_sweep, trial_config

RESULTS_LINK = ".results"       # <sweep>/.results/<results name> -> <sweep>: the trials' results_dir
LOCK_FILE = ".lock"             # <sweep>/.lock


class SweepLockedError(SweepError):
    """Another driver runs this sweep."""


def lock_sweep(sweep_dir: Path) -> None:
    """Hold the sweep's lock (flock on <sweep>/.lock) for the rest of this driver's life, as a training holds its
    run's; SweepLockedError if another driver holds it. The kernel drops it when the driver ends, however."""
    path = sweep_dir.resolve()
    if not hold_lock(path / LOCK_FILE):
        raise SweepLockedError(f"sweep {path.name}: another ./ws sweep is running it (it holds {path / LOCK_FILE}); "
                               f"wait for it to end (or stop it), then resume:=true name:={path.name}")


def agent_config_file(sweep_dir: Path, trial: Trial) -> Path:
    return sweep_dir / "configs" / f"{trial.name}.agent.yaml"


def _saved_sweep(sweep_dir: Path) -> dict[str, Any] | None:
    """A sweep folder's sweep.yaml (None: there is none, or it is not a sweep's)."""
    try:
        saved = yaml.safe_load((sweep_dir / "sweep.yaml").read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError):
        return None
    return saved if isinstance(saved, dict) and isinstance(saved.get("args"), list) and saved["args"] else None


def find_sweep(spec: SweepSpec) -> Path:
    """The folder of the sweep named `spec.name`, whatever its task and agent: the one <results_dir>/*/<name>/ with a
    sweep.yaml, of spec's robot (and of task:= and agent:= when given); SweepError if none or several."""
    base = Path(spec.results_dir).expanduser().resolve()
    found = {path.parent: saved for path in sorted(base.glob(f"*/{spec.name}/sweep.yaml"))
             if (saved := _saved_sweep(path.parent)) is not None}
    if not found:
        raise SweepError(f"no sweep {spec.name!r} to resume under {base} (no {base}/*/{spec.name}/sweep.yaml)")
    given = {arg.partition(":=")[0]: arg.partition(":=")[2] for arg in spec.grid_args[1:]}

    def matches(saved: dict[str, Any]) -> bool:
        return (saved["args"][0] == spec.robot and ("task" not in given or saved.get("task") == spec.task.env_id)
                and ("agent" not in given or saved.get("agent") == spec.agent.name))
    chosen = [path for path, saved in found.items() if matches(saved)]
    if len(chosen) == 1:
        return chosen[0]
    if not chosen:
        others = ", ".join(f"{path} (./ws sweep {' '.join(saved['args'])})" for path, saved in found.items())
        raise SweepError(f"no {spec.robot} sweep {spec.name!r}{' of that task and agent' if given else ''} under "
                         f"{base}; there is: {others}: resume it with its robot, ./ws sweep ROBOT name:={spec.name} "
                         f"resume:=true")
    raise SweepError(f"sweep name {spec.name!r} is in {len(chosen)} results folders ({', '.join(map(str, chosen))}): "
                     f"add the task:= and agent:= of the one to resume")


def resume_sweep(spec: SweepSpec) -> tuple[SweepSpec, Path]:
    """The sweep to resume, locked; its saved arguments define the trials."""
    if not spec.name:
        raise SweepError(f"resume:=true needs the sweep's name:= (a folder under {Path(spec.results_dir)}/*/)")
    sweep_dir = find_sweep(spec)
    lock_sweep(sweep_dir)
    saved = _saved_sweep(sweep_dir)
    if saved is None:
        raise SweepError(f"no sweep {spec.name!r} to resume (no {sweep_dir / 'sweep.yaml'})")
    given = list(spec.grid_args)
    chooses = all(arg.partition(":=")[0] in ("task", "agent") for arg in given[1:])  # only which sweep it is
    if given != saved["args"] and not chooses:
        raise SweepError(f"sweep {spec.name} was started with {' '.join(saved['args'])}; resume:=true continues "
                         f"those trials (give just name:= and resume:=true)")
    options = [f"{k}:={v}" for k, v in (("name", spec.name), ("resume", "true"), ("cluster", spec.cluster),
                                        ("concurrent", spec.concurrent), ("results_dir", spec.results_dir)) if v]
    return parse_sweep([*saved["args"], *options]), sweep_dir


def open_sweep(spec: SweepSpec) -> tuple[SweepSpec, Path]:
    """The sweep's folder, made (new) or found (resume:=true), and this driver holding its lock. A new sweep is
    checked whole (its trials, the agent on the task) before its folder is made, and a start that fails after
    leaves no folder."""
    if spec.resume:
        return resume_sweep(spec)
    root = Path(spec.results_dir).expanduser().resolve() / spec.agent.results_name(spec.task)
    name = spec.name or datetime.datetime.now(datetime.UTC).strftime("%Y%m%d-%H%M%S")
    sweep_dir = root / name
    taken = sorted(path.parent for path in root.parent.glob(f"*/{name}/sweep.yaml"))
    if taken:  # a name is one sweep's under every results folder: resume:=true finds it by its name
        raise SweepError(f"a sweep {taken[0]} exists already: resume:=true name:={name} continues it; a new sweep "
                         f"needs another name:=")
    spec = dataclasses.replace(spec, name=name)
    trials = spec.trials()
    check_agent_fits(spec, trials)
    agent_config = spec.agent.config_for(spec.task)  # the trials' agent configs start from it
    try:
        sweep_dir.mkdir(parents=True)
    except FileExistsError:
        raise SweepError(f"a sweep {sweep_dir} exists already: resume:=true name:={name} continues it; a new sweep "
                         f"needs another name:=") from None
    try:
        lock_sweep(sweep_dir)
        (sweep_dir / "configs").mkdir()
        for trial in trials:
            write_text_atomic(sweep_dir / "configs" / f"{trial.name}.yaml",
                              yaml.safe_dump(trial_config(spec.task, trial, spec.max_steps), sort_keys=False))
            agent_document = sweep_spec.trial_agent_config(spec.agent, spec.task, trial)
            if agent_document is not None:
                write_text_atomic(agent_config_file(sweep_dir, trial),
                                  yaml.safe_dump(agent_document, sort_keys=False))
        (sweep_dir / RESULTS_LINK).mkdir()
        (sweep_dir / RESULTS_LINK / spec.agent.results_name(spec.task)).symlink_to("..")
        write_text_atomic(sweep_dir / "sweep.yaml", yaml.safe_dump(  # last: a folder with it is a whole sweep
            {"args": list(spec.grid_args), "task": spec.task.env_id, "agent": spec.agent.name,
             "agent_config": None if agent_config is None else str(agent_config),
             "max_steps": spec.max_steps or None, "seeds": list(spec.seeds),
             "params": {k: list(v) for k, v in spec.grid}, "trials": [t.name for t in trials]}, sort_keys=False))
    except BaseException:  # a full disk, Ctrl-C, another driver's lock...: no half-made sweep blocks its name
        shutil.rmtree(sweep_dir, ignore_errors=True)
        raise
    return spec, sweep_dir
