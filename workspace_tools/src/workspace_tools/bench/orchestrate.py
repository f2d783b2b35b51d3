"""./ws bench's orchestration: every section's repetitions, each configuration in fresh processes, into a report."""
from __future__ import annotations

import datetime
import importlib
import json
import os
import platform
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from robot_rl import find_task
from workspace_tools.bench.common import (
    BC_DAGGER_TINY,
    DEEP_STEPS,
    DISTRIBUTED_ENVS,
    END_TO_END_STEPS,
    RECOVERY_STEPS_BEFORE_LOSS,
    ROBOTS,
    SCALING_ENVS,
    SWEEP_EPISODES,
    SWEEP_EVAL_EPISODES,
    stat_fields,
)
from workspace_tools.bench.rllib import rllib_rep, rllib_summary
from workspace_tools.processes import Processes, RosMaster, launch_args
from workspace_tools.robots import ROBOTS as ROBOT_REGISTRY

CUBE = ROBOT_REGISTRY["cube"]  # the training and sweep sections train the cube

def _run_worker(processes: Processes, args: list, timeout: float) -> dict:
    result = processes.run([sys.executable, "-m", "workspace_tools.bench.workers", *map(str, args)], timeout=timeout)
    if result.returncode != 0:
        raise RuntimeError(f"bench worker {' '.join(map(str, args))} failed:\n{result.stderr[-3000:]}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def _run_module(processes: Processes, args: list, timeout: float) -> dict:
    """Run `python -m MODULE ARGS...` (args[0] the module) and return the JSON of its last line."""
    result = processes.run([sys.executable, "-m", *map(str, args)], timeout=timeout)
    if result.returncode != 0:
        raise RuntimeError(f"bench worker {' '.join(map(str, args))} failed:\n{result.stderr[-3000:]}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def _with_sim(log_dir: Path, robot: str, real_time_factor: float, worker_args: list) -> dict:
    master = RosMaster(log_dir)
    try:
        master.start([*ROBOTS[robot].task.robot.sim_launch.split(), *launch_args(
            paused="true", real_time_factor=real_time_factor, robot_state_publisher="false")],
            stdout=(log_dir / "sim.log").open("w"), stderr=subprocess.STDOUT)
        return _run_worker(master, worker_args, timeout=600)
    finally:
        master.close()


def _independent_direct(log_dir: Path, robot: str, n: int, steps: int, running_step: float) -> float:
    """Env steps/s of n one-env direct processes started at once, each on its own (no vector env, no ROS):
    all their steps over the wall time from the first start to the last end. What the machine's cores give
    to independent envs: the ceiling for a vector env's scaling in the same run."""
    processes = Processes(log_dir)
    args = ["lockstep", robot, "direct", steps, running_step]
    try:
        with ThreadPoolExecutor(n) as pool:
            results = list(pool.map(lambda _: _run_worker(processes, args, timeout=600), range(n)))
    finally:
        processes.close()
    return n * steps / (max(r["wall_end"] for r in results) - min(r["wall_start"] for r in results))


def _cube_training_wall_time(log_dir: Path, episodes: int) -> float:
    master = RosMaster(log_dir)
    results = log_dir / "results"
    try:
        result = master.run(["rosrun", "workspace_tools", "roslaunch_checked.py", *CUBE.training_launch,
                             *launch_args(results_dir=results, nepisodes=episodes, video="false")], timeout=900)
    finally:
        master.close()
    if result.returncode != 0:
        raise RuntimeError(f"cube training failed:\n{result.stdout[-3000:]}")
    return json.loads((results / _cube_results_name() / "latest" / "summary.json").read_text())["wall_time_s"]


def _cube_results_name() -> str:
    """The folder the cube's default task writes its runs to, below results_dir."""
    return find_task(list(importlib.import_module(CUBE.package).TASKS), CUBE.default_task).results_name


def _sweep_wall_time(folder: Path, seeds: str) -> float:
    """Wall seconds of `./ws sweep cube seeds:=SEEDS` (every trial at once), from its start to its exit."""
    folder.mkdir(parents=True)
    started = time.monotonic()
    result = subprocess.run([sys.executable, "-m", "workspace_tools.sweep", "cube", f"seeds:={seeds}",
                             f"nepisodes:={SWEEP_EPISODES}", f"eval_episodes:={SWEEP_EVAL_EPISODES}", "concurrent:=2",
                             "name:=bench", f"results_dir:={folder}"], capture_output=True, text=True, timeout=1800)
    if result.returncode != 0:
        raise RuntimeError(f"sweep seeds:={seeds} failed:\n{result.stdout[-3000:]}{result.stderr[-3000:]}")
    return time.monotonic() - started


def _sweep_recovery_time(folder: Path) -> float:
    """Wall seconds from a node's loss to a sweep trial's training resuming: `./ws sweep cube seeds:=0-1` on a
    three-node LoopbackCluster of one CPU each (a trial on two of them); once both trials have a checkpoint, a
    node other than the head that runs a trial is killed by PID as a machine lost, and the time runs until the
    lost trial, run again by Tune on the free node, says in its training.log that it resumes from its checkpoint.
    The sweep is then ended (its driver's process group killed, then the cluster closed by PID); RuntimeError if
    the trial does not resume in time."""
    from workspace_tools.ray_cluster import LoopbackCluster
    sweep = folder / "results" / _cube_results_name() / "lost"
    logs = [sweep / "logs" / f"seed={seed}" / "training.log" for seed in (0, 1)]
    cluster = LoopbackCluster(folder / "cluster", nodes=3, cpus_per_node=1)
    try:
        env = {**os.environ, **cluster.driver_environment, "ROBOT_RL_CLUSTER_DIR": str(cluster.folder)}
        with open(folder / "sweep.log", "wb") as output:
            driver = subprocess.Popen(
                [sys.executable, "-m", "workspace_tools.sweep", "cube", "seeds:=0-1", "nepisodes:=1000", "nsteps:=100",
                 "name:=lost", "eval_episodes:=1", f"results_dir:={folder / 'results'}", f"cluster:={cluster.address}"],
                env=env, stdin=subprocess.DEVNULL, stdout=output, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            _wait(lambda: all((sweep / f"seed={seed}" / "qtable.json").is_file() for seed in (0, 1)), 600,
                  f"both trials' first checkpoints (qtable.json in {sweep}/seed=*; log {folder / 'sweep.log'})")
            lost = next((i for i in (1, 2) if _runs_training(cluster.processes(), cluster.processes_started[i].pid)),
                        None)
            if lost is None:
                raise RuntimeError(f"no trial runs on a node other than the head (log {folder / 'sweep.log'})")
            killed = time.monotonic()
            cluster.kill_node(lost)
            _wait(lambda: any(log.is_file() and "Resuming" in log.read_text() for log in logs), 600,
                  f"the lost trial's training resuming ('Resuming' in {sweep}/logs/seed=*/training.log)")
            return time.monotonic() - killed
        finally:
            os.killpg(driver.pid, signal.SIGKILL)  # its trials end with it (Ray), their launches by their death signal
            driver.wait(30)
    finally:
        cluster.close()


def _runs_training(pids: list[int], node: int) -> bool:
    """Whether any of `pids` is a training launch's node started under the node whose `ray start` is `node`."""
    for pid in pids:
        try:
            if b"start_training" not in Path(f"/proc/{pid}/cmdline").read_bytes():
                continue
            while pid > 1 and pid != node:
                pid = int(stat_fields(pid)[1])
        except OSError:  # gone
            continue
        if pid == node:
            return True
    return False


def _wait(condition: Any, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise RuntimeError(f"no {what} within {timeout:.0f} s")
        time.sleep(0.1)


def _machine() -> str:
    import os
    from importlib.metadata import version

    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor())
    debian = Path("/etc/debian_version")
    system = f"Debian {debian.read_text().strip()}" if debian.exists() else platform.platform()
    return (f"{cpu}, {os.cpu_count()} cores, Linux {platform.release()}, {system}, Python "
            f"{platform.python_version()}, pybullet {version('pybullet')}")


def _log(message: str) -> None:
    print(f"[bench] {message}", file=sys.stderr, flush=True)


def _rep(tmp: Path, rep: int, robot: str, running_step: float, sections: set[str], samples: dict) -> None:
    """One repetition of every section for one robot, each configuration in fresh processes."""
    spec, s = ROBOTS[robot], samples[robot]
    steps = round(spec.sim_seconds / running_step)
    tag = f"{tmp}/{rep}-{robot}"
    if "lockstep" in sections:
        ros = _with_sim(Path(f"{tag}-ros"), robot, 0.0, ["lockstep", robot, "ros", steps, running_step])
        direct = _run_worker(Processes(Path(f"{tag}-direct")), ["lockstep", robot, "direct", steps, running_step],
                             timeout=600)
        s["ros"].append(ros["steps_per_s"])
        s["direct"].append(direct["steps_per_s"])
        for part, value in (*ros["cpu_us_per_step"].items(), *direct["cpu_us_per_step"].items()):
            s[f"cpu_{part}"].append(value)
        s["ratio"].append(ros["steps_per_s"] / direct["steps_per_s"])
        for backend, result in (("ros", ros), ("direct", direct)):
            s[f"{backend}_lockstep_bound_2"].append(result["lockstep_speedup_bound_2"])
        _log(f"rep {rep + 1} {robot}: one env over ROS {ros['steps_per_s']:.0f}/s, "
             f"direct {direct['steps_per_s']:.0f}/s")
        if robot == "hopper":  # the end-to-end task (issue 39): the teacher acting, every 5 ms
            e2e = {"ros": _with_sim(Path(f"{tag}-e2e-ros"), robot, 0.0, ["end_to_end", robot, "ros", END_TO_END_STEPS]),
                   "direct": _run_worker(Processes(Path(f"{tag}-e2e-direct")),
                                         ["end_to_end", robot, "direct", END_TO_END_STEPS], timeout=600)}
            for backend, result in e2e.items():
                s[f"end_to_end_{backend}"].append(result["steps_per_s"])
                s["end_to_end_teacher_us"].append(result["teacher_us_per_step"])
            s["end_to_end_ratio"].append(e2e["ros"]["steps_per_s"] / e2e["direct"]["steps_per_s"])
            _log(f"rep {rep + 1} {robot}: end_to_end, the teacher acting: over ROS {e2e['ros']['steps_per_s']:.0f}/s, "
                 f"direct {e2e['direct']['steps_per_s']:.0f}/s")
    if "scaling" in sections:
        for backend in ("ros", "direct"):
            rates = {}
            for n in SCALING_ENVS:
                result = _run_worker(Processes(Path(f"{tag}-vector-{backend}-{n}")),
                                     ["vector", robot, backend, n, steps * n, running_step], timeout=900)
                rates[n] = result["steps_per_s"]
                s[f"{backend}_vector_{n}"].append(rates[n])
                s[f"{backend}_cpu_{n}"].append(result["cpu_ms_per_step"])
            for n in SCALING_ENVS[1:]:
                s[f"{backend}_efficiency_{n}"].append(rates[n] / (n * rates[1]))
            _log(f"rep {rep + 1} {robot}: vector env {backend}: " + ", ".join(
                f"N={n} {rate:.0f}/s" for n, rate in rates.items()))
        qlearn = {n: _run_worker(Processes(Path(f"{tag}-qlearn-{n}")), ["qlearn", robot, n, steps * n, running_step],
                                 timeout=900)["steps_per_s"] for n in (1, 2)}
        s["qlearn_1"].append(qlearn[1])
        s["qlearn_2"].append(qlearn[2])
        s["qlearn_speedup_2"].append(qlearn[2] / qlearn[1])
        _log(f"rep {rep + 1} {robot}: tabular Q-learning from N envs over ROS: N=1 {qlearn[1]:.0f}/s, "
             f"N=2 {qlearn[2]:.0f}/s")
        alone, together = (_independent_direct(Path(f"{tag}-independent-{n}"), robot, n, 2 * steps, running_step)
                           for n in (1, 2))
        s["independent_speedup_2"].append(together / alone)
        _log(f"rep {rep + 1} {robot}: independent direct processes: 1 alone {alone:.0f}/s, 2 at once {together:.0f}/s")
    if "deep" in sections:
        ros = _with_sim(Path(f"{tag}-deep-ros"), robot, 0.0, ["deep", robot, "ros", DEEP_STEPS, running_step])
        direct = _run_worker(Processes(Path(f"{tag}-deep-direct")), ["deep", robot, "direct", DEEP_STEPS,
                                                                     running_step], timeout=900)
        s["deep_ros"].append(ros["steps_per_s"])
        s["deep_direct"].append(direct["steps_per_s"])
        s["deep_ratio"].append(ros["steps_per_s"] / direct["steps_per_s"])
        _log(f"rep {rep + 1} {robot}: DQN over ROS {ros['steps_per_s']:.0f}/s, direct {direct['steps_per_s']:.0f}/s")
        if robot == "hopper":  # agent bc_dagger on the end-to-end task, a tiny budget, direct
            bc_dagger = _run_worker(Processes(Path(f"{tag}-bc_dagger")), ["bc_dagger", robot], timeout=900)
            s["bc_dagger_samples_per_s"].append(bc_dagger["samples_per_s"])
            _log(f"rep {rep + 1} {robot}: bc_dagger direct {bc_dagger['samples_per_s']:.0f} samples/s "
                 f"({bc_dagger['samples']} in {bc_dagger['wall_s']:.1f} s, fitting {bc_dagger['fit_s']:.1f} s)")
    if "distributed" in sections:
        _distributed_rep(Path(f"{tag}-distributed"), rep, robot, steps, running_step, s)
    if "rllib" in sections and robot == "cube":
        rllib_rep(lambda folder, args: _run_module(Processes(folder), args, timeout=600), Path(f"{tag}-rllib"), rep,
                  running_step, s, _log)
    if "gazebo" in sections:
        for rtf, gazebo_steps in spec.gazebo_steps.items():
            style = _with_sim(Path(f"{tag}-gazebo{rtf}"), robot, rtf, ["gazebo", robot, gazebo_steps, running_step])
            s[f"gazebo_{int(rtf)}"].append(style["steps_per_s"])


def _distributed_rep(folder: Path, rep: int, robot: str, steps: int, running_step: float, s: dict) -> None:
    """Pipe workers and Ray actors at N = 1 and 2, interleaved, with a one-node Ray cluster up throughout."""
    from workspace_tools.ray_cluster import LoopbackCluster
    with LoopbackCluster(folder / "cluster", nodes=1, cpus_per_node=os.cpu_count() or 1) as cluster:
        rates = {}
        for n in DISTRIBUTED_ENVS:
            for transport, address, mark in (("pipe", "", ""), ("ray", cluster.address, cluster.mark)):
                processes = Processes(folder / f"{transport}-{n}", ROBOT_RL_CLUSTER_DIR=str(cluster.folder))
                result = _run_worker(processes, ["vector", robot, "ros", n, steps * n, running_step, address, mark],
                                     timeout=900)
                rates[transport, n] = result["steps_per_s"]
                s[f"distributed_{transport}_{n}"].append(rates[transport, n])
                s[f"distributed_cpu_{transport}_{n}"].append(result["cpu_ms_per_step"])
            s[f"ray_to_pipe_{n}"].append(rates["ray", n] / rates["pipe", n])
    _log(f"rep {rep + 1} {robot}: vector env over ROS, Ray actors / pipe workers: " + ", ".join(
        f"N={n} {rates['ray', n]:.0f}/{rates['pipe', n]:.0f} steps/s = {rates['ray', n] / rates['pipe', n]:.2f}"
        for n in DISTRIBUTED_ENVS))
    recovery = _run_worker(Processes(folder / "recovery"), ["recovery", robot, RECOVERY_STEPS_BEFORE_LOSS,
                                                            running_step, folder / "recovery-cluster"], timeout=900)
    s["node_loss_recovery_s"].append(recovery["recovery_s"])
    s["actors_start_s"].append(recovery["start_s"])
    _log(f"rep {rep + 1} {robot}: a node lost: its actor's env stepped again {recovery['recovery_s']:.1f} s after "
         f"the kill (the 2 actors started in {recovery['start_s']:.1f} s)")


def orchestrate(reps: int, output: Path, running_steps: dict[str, float], sections: set[str]) -> dict:
    samples: dict[str, dict[str, list[float]]] = {robot: defaultdict(list) for robot in ROBOTS}
    cube_training = []
    sweeps: list[tuple[float, float]] = []  # trials per hour: one trial alone, two at once
    sweep_recovery: list[float] = []  # s from a node's loss to its trial's training resuming
    with tempfile.TemporaryDirectory(prefix="bench-") as tmp_dir:
        tmp = Path(tmp_dir)
        for rep in range(reps):
            for robot in ROBOTS:
                _rep(tmp, rep, robot, running_steps[robot], sections, samples)
            if "training" in sections:
                cube_training.append(_cube_training_wall_time(tmp / f"{rep}-training", 100))
                _log(f"rep {rep + 1}/{reps}: 100 cube training episodes in {cube_training[-1]:.1f} s")
            if "distributed" in sections:
                sweep_recovery.append(_sweep_recovery_time(tmp / f"{rep}-sweep-recovery"))
                _log(f"rep {rep + 1}/{reps}: a node lost mid-sweep: its trial resumed {sweep_recovery[-1]:.1f} s after "
                     f"the kill")
            if "sweeps" in sections:
                one, two = (_sweep_wall_time(tmp / f"{rep}-sweep-{n}", seeds) for n, seeds in ((1, "0"), (2, "0-1")))
                sweeps.append((3600 / one, 2 * 3600 / two))
                _log(f"rep {rep + 1}/{reps}: sweeps: 1 trial in {one:.0f} s, 2 at once in {two:.0f} s: "
                     f"{sweeps[-1][1] / sweeps[-1][0]:.2f}x the trials per hour")
    median = statistics.median
    report: dict[str, Any] = {
        "machine": _machine(), "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "load_average_at_end": os.getloadavg()[0], "repetitions": reps, "sections": sorted(sections)}
    for robot in ROBOTS:
        s = samples[robot]
        r: dict[str, Any] = {"running_step": running_steps[robot],
                             "config_running_step": ROBOTS[robot].task.default_params().running_step}
        if "lockstep" in sections:
            r.update(ros_lockstep_steps_per_s=median(s["ros"]), direct_steps_per_s=median(s["direct"]),
                     ratio_ros_to_direct=median(s["ratio"]),
                     ros_lockstep_real_time_factor=median(s["ros"]) * running_steps[robot],
                     lockstep_speedup_bound={backend: {"2": median(s[f"{backend}_lockstep_bound_2"])}
                                             for backend in ("ros", "direct")},
                     cpu_us_per_step={"ros": {part: median(s[f"cpu_{part}"]) for part in ("client", "sim_node")},
                                      "direct": {part: median(s[f"cpu_{part}"])
                                                 for part in ("physics", "sensors_and_task")}})
            if s.get("end_to_end_ros"):
                r["end_to_end"] = {"steps": END_TO_END_STEPS, "actions": "the teacher's",
                                   "ros_steps_per_s": median(s["end_to_end_ros"]),
                                   "direct_steps_per_s": median(s["end_to_end_direct"]),
                                   "ratio_ros_to_direct": median(s["end_to_end_ratio"]),
                                   "teacher_us_per_step": median(s["end_to_end_teacher_us"])}
        if "scaling" in sections:
            r["scaling"] = {backend: {
                "envs": list(SCALING_ENVS),
                "steps_per_s": {str(n): median(s[f"{backend}_vector_{n}"]) for n in SCALING_ENVS},
                "parallel_efficiency": {str(n): median(s[f"{backend}_efficiency_{n}"]) for n in SCALING_ENVS[1:]},
                "speedup": {str(n): n * median(s[f"{backend}_efficiency_{n}"]) for n in SCALING_ENVS[1:]},
                "cpu_ms_per_step": {str(n): median(s[f"{backend}_cpu_{n}"]) for n in SCALING_ENVS},
            } for backend in ("ros", "direct")}
            r["scaling"]["independent_direct_processes_speedup"] = {"2": median(s["independent_speedup_2"])}
            r["scaling"]["qlearn_ros"] = {"steps_per_s": {str(n): median(s[f"qlearn_{n}"]) for n in (1, 2)},
                                          "speedup": {"2": median(s["qlearn_speedup_2"])}}
        if "deep" in sections:
            r["dqn"] = {"steps": DEEP_STEPS, "ros_steps_per_s": median(s["deep_ros"]),
                        "direct_steps_per_s": median(s["deep_direct"]), "ratio_ros_to_direct": median(s["deep_ratio"])}
            if s.get("bc_dagger_samples_per_s"):
                r["bc_dagger"] = {"budget": dict(BC_DAGGER_TINY),
                                  "direct_samples_per_s": median(s["bc_dagger_samples_per_s"])}
        if "distributed" in sections:
            r["distributed"] = {
                "envs": list(DISTRIBUTED_ENVS),
                "steps_per_s": {transport: {str(n): median(s[f"distributed_{transport}_{n}"]) for n in DISTRIBUTED_ENVS}
                                for transport in ("pipe", "ray")},
                "ratio_ray_to_pipe": {str(n): median(s[f"ray_to_pipe_{n}"]) for n in DISTRIBUTED_ENVS},
                "cpu_ms_per_step": {transport: {str(n): median(s[f"distributed_cpu_{transport}_{n}"])
                                                for n in DISTRIBUTED_ENVS} for transport in ("pipe", "ray")},
                "node_loss_recovery_s": median(s["node_loss_recovery_s"]),
                "actors_start_s": median(s["actors_start_s"])}
        if "rllib" in sections and robot == "cube":
            r["rllib"] = rllib_summary(s, median)
        if "gazebo" in sections:
            r.update(gazebo_style_rtf1_steps_per_s=median(s["gazebo_1"]),
                     gazebo_style_max_speed_steps_per_s=median(s["gazebo_0"]))
        r["per_repetition"] = dict(s)
        report[robot] = r
    if "training" in sections:
        report["cube_100_episodes_wall_s"] = median(cube_training)
    if "distributed" in sections:
        report["sweep_node_loss_recovery_s"] = median(sweep_recovery)
    if "sweeps" in sections:
        report["sweeps"] = {"episodes_per_trial": SWEEP_EPISODES,
                            "trials_per_hour": {"1": median(one for one, _ in sweeps),
                                                "2": median(two for _, two in sweeps)},
                            "ratio_2_to_1": median(two / one for one, two in sweeps),
                            "per_repetition": [list(pair) for pair in sweeps]}
    output.write_text(json.dumps(report, indent=2) + "\n")
    return report
