"""`./ws sweep`: many whole training runs of one task (trials) over seeds and training params, on Ray Tune.

  python -m workspace_tools.sweep [ROBOT] [task:=T] [agent:=A] [seeds:=0-9] [NAME:=v1,v2 ...] [max_steps:=N]
                                  [name:=SWEEP] [resume:=true] [cluster:=ADDRESS] [concurrent:=N]
                                  [max_failures:=N] [eval_episodes:=N] [eval_seed:=S] [results_dir:=DIR]

The grammar and the trials' names: workspace_tools.sweep_spec. Each trial is one Ray Tune trial (one
CPU) that runs today's training exactly as `./ws run` does (roslaunch_checked.py and the robot's
main.launch, on a ROS master of its own on a free loopback port, video:=false) with a config that is the
task's YAML with the trial's seed and parameters (and, for a deep agent, an agent_config:= that is the
agent's default file for the task with the trial's agent parameters), then evaluates the trained run in-process with
evaluate.py's code (robot_rl.evaluation: greedy and random, eval_episodes each, direct backend,
evaluation seed eval_seed, evaluate.py's default initial tilt) into evaluation.json. Everything goes to the
sweep's folder DIR/<results name>/<SWEEP>/ (SWEEP: name:=, else the UTC time):

  sweep.yaml            the arguments that define the trials, and the trials
  configs/<trial>.yaml  each trial's config (configs/<trial>.agent.yaml: a deep agent's)
  <trial>/              each trial's run folder, as ./ws run writes one, plus evaluation.json
  logs/<trial>/         each trial's roslaunch output (training.log) and ROS logs
  tune/                 Ray Tune's own folder (its storage path)
  sweep.md, sweep.csv   the table (workspace_tools.sweep_table); learning_curves.png: every trial's curve
                        and the mean

The run folders are the source of truth: a trial whose folder holds a completed summary.json and
evaluation.json is done; one with a checkpoint continues from it (resume:=true of the training node:
episodes after the checkpoint are dropped and re-run, none repeated or lost); one without a checkpoint
starts anew (removed under the run's lock only: never while a training holds it). So a failed trial (Tune
retries it up to max_failures times) and an interrupted sweep (`resume:=true name:=SWEEP`, which runs the
trials not done, found by its name under every results folder of DIR) go on where their runs' checkpoints
are. The driver holds the sweep's lock (<sweep>/.lock) for its life: a second driver of it stops in one line.
A new sweep is checked whole (its trials, at most sweep_spec.MAX_TRIALS; the agent on each distinct env)
before its folder is made, and a start that fails after removes it.
One line per finished trial, with an ETA. Ray runs on this machine (a private temp dir, no dashboard, no
usage statistics; Ray 2.60 listens on every interface whatever address it is given, and a local instance
has its token authentication on, its default: docs/guide/distributed.md) unless cluster:=ADDRESS names a
running cluster. Every ROS master and sim node of a trial is on 127.0.0.1.
SIGTERM or SIGINT (Ctrl-C) ends the driver within seconds (`_stop_on_signals`; Tune's own graceful stop took 19 s):
it leaves Tune's wait at once, and its connection's end ends the trials under way as a killed driver's does (Ray
kills each trial's actor and its launch; the run keeps its last checkpoint); the table of the trials done is
written (the curves are left for the resumed sweep), and resume:=true goes on from each run's checkpoint.
Exit codes: 0 every trial done, 1 a trial failed (the table has the others) or another driver runs the
sweep, 2 bad arguments, 130 interrupted.
"""
from __future__ import annotations

import contextlib
import dataclasses
import datetime
import importlib
import json
import logging
import math
import os
import platform
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robot_rl import (
    ClusterError,
    RunDirectory,
    cluster,
    format_duration,
    free_port,
    lock_while,
    prepare_child,
    stop_process,
    write_json_atomic,
)
from workspace_tools.processes import launch_args
from workspace_tools.robots import robot_of_package
from workspace_tools.sweep_folder import RESULTS_LINK, SweepLockedError, agent_config_file, open_sweep
from workspace_tools.sweep_spec import SweepError, SweepSpec, Trial, format_value, parse_sweep
from workspace_tools.sweep_table import TrialResult, plot_curves, write_table

INTERRUPTED = 130
TRIAL_TIMEOUT_S = 24 * 3600.0   # one training run, at most
LOG_TAIL_CHARS = 2000
LOCK_FILE = ".lock"             # each trial's <trial>/.lock: robot_rl's run lock


def _log(message: str) -> None:
    print(f"[sweep] {message}", file=sys.stderr, flush=True)


@dataclass(frozen=True)
class TrialJob:
    """Everything a trial needs, as plain values (it crosses to a Ray worker in Tune's config)."""

    name: str
    seed: int
    params: dict[str, Any]      # the varied parameters (the table's columns)
    sweep_dir: str
    package: str
    task: str
    agent: str
    results_name: str
    checkpoint_name: str
    eval_episodes: int
    eval_seed: int
    agent_config: str = ""      # the trial's agent_config:= ("": the agent has no params of its own)
    max_steps: int = 0          # a deep agent's env step budget (0: nepisodes decides)

    @property
    def run_dir(self) -> Path:
        return Path(self.sweep_dir) / self.name

    @property
    def config_file(self) -> Path:
        return Path(self.sweep_dir) / "configs" / f"{self.name}.yaml"

    @property
    def log_dir(self) -> Path:
        return Path(self.sweep_dir) / "logs" / self.name


def _read_json(path: Path) -> dict[str, Any] | None:
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return value if isinstance(value, dict) else None


def trial_done(job: TrialJob) -> bool:
    summary = _read_json(job.run_dir / "summary.json")
    return bool(summary and summary.get("completed")) and (job.run_dir / "evaluation.json").is_file()


@contextlib.contextmanager
def _run_locked(job: TrialJob) -> Iterator[None]:
    """The trial's run lock (robot_rl's flock on <run>/.lock, which every training of the run holds) while the
    block runs; RuntimeError naming the run if a training process holds it."""
    with lock_while(job.run_dir / LOCK_FILE) as held:
        if not held:
            raise RuntimeError(f"trial {job.name}: another process is training its run {job.run_dir} (it holds "
                               f"{job.run_dir / LOCK_FILE}); nothing of it was changed")
        yield


def _train(job: TrialJob) -> None:
    """Train the trial's run to its end: anew, or on from its checkpoint (as ./ws run ... resume:=true)."""
    run = job.run_dir
    resume = (run / job.checkpoint_name).is_file()
    if run.exists() and not resume:
        with _run_locked(job):  # never under a training that still writes it
            shutil.rmtree(run)  # it ended before its first checkpoint: nothing in it counts, start anew
    job.log_dir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}", ROS_HOSTNAME="127.0.0.1",
               ROS_IP="127.0.0.1", ROS_LOG_DIR=str(job.log_dir), ROS_HOME=str(job.log_dir))
    task_arg = [f"task:={job.task}"] if robot_of_package(job.package).task_arg else []
    agent_args = launch_args(**{"agent_config": job.agent_config} if job.agent_config else {},
                             **{"max_steps": job.max_steps} if job.max_steps else {})
    command = ["rosrun", "workspace_tools", "roslaunch_checked.py", job.package, "main.launch", *task_arg,
               # seed:= as ./ws run seed:=S passes it: the launch gives it to the sim (its sensor noise) too
               *launch_args(config=job.config_file, results_dir=Path(job.sweep_dir) / RESULTS_LINK, run=job.name,
                            seed=job.seed, resume=str(resume).lower(), agent=job.agent, video="false", quiet="true"),
               *agent_args]
    log_path = job.log_dir / "training.log"
    with open(log_path, "ab") as log:
        log.write(f"\n=== {datetime.datetime.now(datetime.UTC).isoformat()} {' '.join(command)}\n".encode())
        log.flush()
        # prepare_child: the launcher gets SIGTERM if this trial's process dies (its launch reaper ends the rest),
        # and SIGINT as a terminal gives it (Tune's trial thread blocks SIGINT, and a child inherits the mask:
        # roslaunch's SIGINT to its master would then wait 15 s before SIGTERM)
        process = subprocess.Popen(command, env=env, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                   preexec_fn=prepare_child)
    try:
        code = process.wait(TRIAL_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise RuntimeError(f"trial {job.name}: training did not end within {TRIAL_TIMEOUT_S:.0f} s; log "
                           f"{log_path}") from None
    finally:
        stop_process(process, group=False)
    if code != 0:
        tail = log_path.read_text(errors="replace")[-LOG_TAIL_CHARS:]
        raise RuntimeError(f"trial {job.name}: training exited with code {code}; log {log_path}:\n{tail}")


def _evaluate(job: TrialJob) -> dict[str, Any]:
    """evaluation.json of the trained run (robot_rl.evaluation, direct backend), written once."""
    path = job.run_dir / "evaluation.json"
    existing = _read_json(path)
    if existing is not None:
        return existing
    from robot_rl import TrainedRun, default_initial_tilt, evaluate
    tasks = importlib.import_module(job.package).TASKS
    run = TrainedRun(job.run_dir, tasks)
    report = evaluate(run, episodes=job.eval_episodes, horizon_s=run.task.eval_horizon_s, backend="direct",
                      seed=job.eval_seed, initial_tilt=default_initial_tilt(run.params))
    write_json_atomic(path, report)
    return report


def run_trial_job(job: TrialJob) -> dict[str, Any]:
    """Train (unless done) and evaluate one trial; returns its numbers for Tune."""
    started = time.monotonic()
    summary = _read_json(job.run_dir / "summary.json")
    if not (summary and summary.get("completed")):
        _train(job)
        summary = _read_json(job.run_dir / "summary.json")
        if not (summary and summary.get("completed")):
            raise RuntimeError(f"trial {job.name}: training ended without a completed summary.json in {job.run_dir}")
    evaluation = _evaluate(job)
    return {"trial_wall_s": time.monotonic() - started, "episodes": summary["episodes"],
            "env_steps": summary["env_steps"],
            **{f"greedy_{k}": v for k, v in evaluation["greedy"].items() if v is not None}}


def run_trial(config: dict[str, Any]) -> None:
    """Ray Tune's function trainable: one trial."""
    from ray import tune
    tune.report(run_trial_job(TrialJob(**config["job"])))


# -- the driver ----------------------------------------------------------------------------------------------

def _greedy_key(headline: str, greedy: dict[str, Any]) -> str:
    return f"{headline}_rate" if f"{headline}_rate" in greedy else f"mean_{headline}"


def _machine() -> str:
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor())
    return f"{cpu}, {os.cpu_count()} cores"


class Progress:
    """One line per finished trial, with an ETA from this session's rate (a Ray Tune callback once wrapped)."""

    def __init__(self, total: int, done_before: int, headline: str):
        self.total, self.done, self.headline = total, done_before, headline
        self.done_here = 0
        self.started = time.monotonic()

    def finished(self, name: str, result: dict[str, Any]) -> str:
        self.done += 1
        self.done_here += 1
        elapsed = time.monotonic() - self.started
        eta = (self.total - self.done) * elapsed / self.done_here
        key = next((k for k in result if k.startswith("greedy_") and self.headline in k), None)
        greedy = f", greedy {key[len('greedy_'):]} {result[key]:.3g}" if key else ""
        return (f"trial {self.done}/{self.total} done: {name}: {result.get('episodes', '?')} episodes, "
                f"{result.get('env_steps', '?')} env steps in {result.get('trial_wall_s', math.nan):.0f} s{greedy}; "
                f"ETA {format_duration(eta if self.done < self.total else 0.0)}")


def _tune_callback(progress: Progress) -> Any:
    from ray import tune

    class ProgressCallback(tune.Callback):
        def on_trial_result(self, iteration: int, trials: list[Any], trial: Any, result: dict[str, Any],
                            **info: Any) -> None:
            _log(progress.finished(trial.config["job"]["name"], result))

        def on_trial_recover(self, iteration: int, trials: list[Any], trial: Any, **info: Any) -> None:
            _log(f"trial {trial.config['job']['name']} failed; it runs again from its checkpoint "
                 f"(logs: {trial.config['job']['sweep_dir']}/logs/{trial.config['job']['name']})")

        def on_trial_error(self, iteration: int, trials: list[Any], trial: Any, **info: Any) -> None:
            _log(f"trial {trial.config['job']['name']} failed for good (max_failures reached); its error: "
                 f"{trial.error_file}")
    return ProgressCallback()


def _jobs(spec: SweepSpec, sweep_dir: Path, trials: Sequence[Trial]) -> list[TrialJob]:
    has_config = spec.agent.params is not None
    return [TrialJob(name=t.name, seed=t.seed, params={k: (t.changes | t.agent_changes)[k] for k in spec.varied},
                     sweep_dir=str(sweep_dir), package=spec.package, task=spec.task.name, agent=spec.agent.name,
                     results_name=spec.agent.results_name(spec.task), checkpoint_name=spec.agent.checkpoint_name,
                     eval_episodes=spec.eval_episodes, eval_seed=spec.eval_seed,
                     agent_config=str(agent_config_file(sweep_dir, t)) if has_config else "",
                     max_steps=spec.max_steps) for t in trials]


@contextlib.contextmanager
def _stop_on_signals() -> Iterator[list[int]]:
    """While the block runs (the driver's Ray part): the first SIGTERM or SIGINT raises KeyboardInterrupt in the
    main thread, which leaves Tune's wait (a KeyboardInterrupt is what Ray's waits pass on from a signal handler),
    later ones are only recorded; Tune's own SIGINT handler is off (its graceful stop takes 10 s or more). Yields
    the signals received; the previous handlers are back after the block."""
    received: list[int] = []

    def stop(signum: int, _frame: Any) -> None:
        received.append(signum)
        if len(received) == 1:
            raise KeyboardInterrupt(signal.Signals(signum).name)
    previous = {signum: signal.getsignal(signum) for signum in (signal.SIGTERM, signal.SIGINT)}
    os.environ["TUNE_DISABLE_SIGINT_HANDLER"] = "1"
    for signum in previous:
        signal.signal(signum, stop)
    try:
        yield received
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _start_ray(spec: SweepSpec, temp_dir: Path | None) -> None:
    """Join `spec.cluster` (robot_rl.workers.cluster.connect: "ray" or HOST:PORT, bounded), else start Ray on this
    machine, its temp folder inside `temp_dir` (private: robot_rl.workers.cluster.new_temp_dir)."""
    if spec.cluster:
        from robot_rl import connect
        connect(spec.cluster)
        return
    assert temp_dir is not None, "a local Ray needs its temp folder"
    import ray
    handlers = {signum: signal.getsignal(signum) for signum in (signal.SIGTERM, signal.SIGINT)}
    ray.init(address="local", num_cpus=spec.concurrent or None, include_dashboard=False,
             _temp_dir=str(cluster.ray_dir(temp_dir)), _node_ip_address="127.0.0.1", object_store_memory=100 * 2**20,
             log_to_driver=False, logging_level=logging.WARNING)
    for signum, handler in handlers.items():  # ray.init sets its own SIGTERM handler (sys.exit)
        signal.signal(signum, handler)
    cluster.make_private(temp_dir)


def _tune(spec: SweepSpec, sweep_dir: Path, jobs: list[TrialJob], progress: Progress) -> list[str]:
    """Run the jobs as Tune trials; returns the names of those that failed for good."""
    from ray import tune
    sessions = sweep_dir / "tune"
    session = f"session-{len(list(sessions.glob('session-*'))) + 1}" if sessions.is_dir() else "session-1"
    tuner = tune.Tuner(
        tune.with_resources(run_trial, {"cpu": 1}),
        param_space={"job": tune.grid_search([dataclasses.asdict(job) for job in jobs])},
        tune_config=tune.TuneConfig(max_concurrent_trials=spec.concurrent, reuse_actors=False,
                                    trial_name_creator=lambda trial: trial.config["job"]["name"],
                                    trial_dirname_creator=lambda trial: trial.config["job"]["name"]),
        run_config=tune.RunConfig(name=session, storage_path=str(sessions), verbose=0,
                                  failure_config=tune.FailureConfig(max_failures=spec.max_failures),
                                  callbacks=[_tune_callback(progress)]))
    grid = tuner.fit()
    results = (grid[i] for i in range(len(grid)))
    return [result.config["job"]["name"] for result in results if result.error is not None and result.config]


def collect_results(spec: SweepSpec, jobs: Sequence[TrialJob]) -> list[TrialResult]:
    """The table's rows: every trial that is done, from its run folder."""
    results = []
    for job in jobs:
        if not trial_done(job):
            continue
        summary = _read_json(job.run_dir / "summary.json") or {}
        evaluation = _read_json(job.run_dir / "evaluation.json") or {}
        records = RunDirectory(job.run_dir, job.checkpoint_name).read_episodes()
        results.append(TrialResult(
            name=job.name, seed=job.seed, params={k: format_value(v) for k, v in job.params.items()},
            episodes=summary["episodes"], env_steps=summary["env_steps"], wall_time_s=summary["wall_time_s"],
            train=summary.get("metrics_last_100", {}), greedy=evaluation.get("greedy", {}),
            random=evaluation.get("random", {}),
            curve=[float(r.metrics.get(spec.task.headline_metric, math.nan)) for r in records]))
    return results


def write_outputs(spec: SweepSpec, sweep_dir: Path, jobs: Sequence[TrialJob], curves: bool = True) -> str:
    results = collect_results(spec, jobs)
    constant = [f"{k}:={','.join(map(format_value, v))}" for k, v in spec.grid if len(v) == 1]
    greedy_key = _greedy_key(spec.task.headline_metric, results[0].greedy if results else {})
    agent_config = spec.agent.config_for(spec.task)
    agent = f"agent {spec.agent.name}" + (f" (from {agent_config.name})" if agent_config is not None else "")
    title = (f"Sweep {spec.name}: {spec.task.env_id}, {agent}, {len(results)} of {len(jobs)} "
             f"trials{' (' + ', '.join(constant) + ')' if constant else ''}; training metrics over the last 100 "
             f"episodes; greedy and random: {spec.eval_episodes} episodes each, direct backend, evaluation seed "
             f"{spec.eval_seed}. `./ws sweep {' '.join(spec.grid_args)} name:={spec.name}`; {_machine()}, "
             f"{datetime.datetime.now().astimezone().isoformat(timespec='seconds')}")
    text = write_table(results, title, greedy_key, sweep_dir / "sweep.md", sweep_dir / "sweep.csv")
    if curves:  # matplotlib: seconds
        plot_curves(results, spec.task.headline_metric,
                    f"sweep {spec.name}: {spec.task.env_id}, every trial and the mean",
                    sweep_dir / "learning_curves.png")
    return text


def main(argv: Sequence[str]) -> int:
    if any(arg in ("-h", "--help") for arg in argv):
        print(__doc__)
        return 0
    try:
        spec, sweep_dir = open_sweep(parse_sweep(argv))
    except SweepLockedError as error:
        _log(f"error: {error}")
        return 1
    except (SweepError, OSError) as error:
        _log(f"error: {error}")
        return 2
    jobs = _jobs(spec, sweep_dir, spec.trials())
    todo = [job for job in jobs if not trial_done(job)]
    _log(f"sweep {spec.name}: {len(jobs)} trials ({len(jobs) - len(todo)} done before) in {sweep_dir}")
    failed: list[str] = []
    stopped: list[int] = []
    if todo:
        os.environ["RAY_USAGE_STATS_ENABLED"] = "0"
        os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")  # with verbose=0: no tables from Tune, our lines only
        import ray
        # a local Ray's: short (Ray's socket paths must fit 107 bytes) and private (0700); none in a cluster, where
        # a killed driver would leave it behind
        temp_dir = None if spec.cluster else cluster.new_temp_dir()
        with _stop_on_signals() as stopped:
            try:
                _start_ray(spec, temp_dir)
                spec = dataclasses.replace(spec, concurrent=spec.concurrent or
                                           int(ray.cluster_resources().get("CPU", 1)))
                _log(f"at most {spec.concurrent} trials at once, each on one CPU of "
                     f"{ray.cluster_resources().get('CPU')}")
                progress = Progress(len(jobs), len(jobs) - len(todo), spec.task.headline_metric)
                failed = _tune(spec, sweep_dir, todo, progress)
            except (KeyboardInterrupt, ClusterError) as error:
                if not stopped:  # a ClusterError, or a KeyboardInterrupt of no signal of ours
                    if isinstance(error, KeyboardInterrupt):
                        raise
                    _log(f"error: {error}")
                    return 1
                _log(f"stopped ({signal.Signals(stopped[0]).name}): the trials under way end with this driver, each "
                     f"run keeping its last checkpoint")
            finally:
                ray.shutdown()  # its trials' actors end with it, and their launches by their death signal
                if temp_dir is not None:
                    shutil.rmtree(temp_dir, ignore_errors=True)
    print(write_outputs(spec, sweep_dir, jobs, curves=not stopped))
    not_done = [job.name for job in jobs if not trial_done(job)]
    if failed:
        _log(f"{len(failed)} trial(s) failed: {', '.join(failed)} (logs in {sweep_dir / 'logs'}); the table has the "
             f"others; ./ws sweep {spec.robot} name:={spec.name} resume:=true tries them again")
        return 1
    if not_done:
        _log(f"interrupted with {len(not_done)} trial(s) not done; continue with ./ws sweep {spec.robot} "
             f"name:={spec.name} resume:=true")
        return INTERRUPTED
    _log(f"sweep {spec.name} done: {sweep_dir / 'sweep.md'}, {sweep_dir / 'sweep.csv'}, "
         f"{sweep_dir / 'learning_curves.png'}")
    return 0


if __name__ == "__main__":
    code = main(sys.argv[1:])
    # Nothing is left to do, and the interpreter's own end (freeing Ray Tune's and its libraries' objects) takes
    # seconds (6 s on two busy cores): a sweep stopped by a signal must end within 10 s of it.
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
