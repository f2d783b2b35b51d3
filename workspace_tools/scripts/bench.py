#!/usr/bin/env python3
"""./ws bench: env steps per second of both robots, over ROS in lockstep, in-process, and the
tutorials' Gazebo-style step, on the real nodes; the scaling of vector envs; a deep agent's training
over ROS against direct. Prints a table and writes bench_results.json; --markdown also writes the table
as docs/reference/performance.md (with the machine, the date and, with the lockstep section, what made lockstep
fast). Only the sections run are printed.

Every figure is the median of --reps repetitions, each in fresh processes (a new master, a new sim
node, a new client); within a repetition every configuration runs once, so the ROS and direct runs
are interleaved and their ratio holds on a noisy machine (ratios are medians of each repetition's
ratio; with more than one repetition the table also gives each ratio's lowest and highest repetition,
and the JSON every repetition's figure). Actions are random (seeded); episode resets are part of the
measured time, as in training.
Each robot's control period (running_step) is read from its task config; --running-step ROBOT=S
overrides it (e.g. hopper=0.02), and the table and the JSON say which was used.

Sections (--sections, default all):
- lockstep: one env over ROS (the sim node of a roslaunch'd sim launch) and direct (in-process), and
  where a step's CPU time goes: over ROS the client process and the sim node, direct the physics
  (World.step) and the rest (reading the sensors, the task env); and, from each env's step times
  (resets included), the most a vector env that steps 2 such envs together could gain over one
  (lockstep_speedup_bound): its every step waits for the slower env.
- scaling: robot_rl.vector's gymnasium vector env with N = 1, 2, 4 workers, over ROS (each worker
  with its own master and sim node) and direct; parallel efficiency = steps/s at N / (N x at 1); and
  the CPU time per env step of every process involved, which says whether a loss of efficiency is
  work added by more workers; tabular Q-learning from N = 1 and 2 envs over ROS
  (robot_rl.vector_training, whose envs are not stepped together); and two one-env direct
  processes started at once, with no vector env and no ROS, against one alone: what the machine's
  cores give to independent envs, the ceiling the speedups are read against (when it is below
  CEILING_WARNING, the table says that this run did not have two free cores).
- deep: Stable-Baselines3 DQN (robot_rl/config/dqn.yaml) learning for a number of env steps on one
  env over ROS and direct; its env steps per second of wall time, gradient steps included.
- gazebo: the tutorials' Gazebo-style step.
- training: 100 episodes of the cube's `main.launch` training.
- distributed: the gymnasium vector env's env steps/s with its workers as Ray actors (robot_rl.ray_workers)
  against pipe workers, at N = 1 and 2, over ROS, on a one-node Ray cluster of this machine's cores started
  for each repetition (workspace_tools.ray_cluster), its daemons running during both; the ratio Ray / pipe.
  At N = 1 the difference is a Ray actor call's round trip per env step. And the CPU time per env step of
  every process of each (with Ray actors, every process of the cluster too): two cores give a way of stepping
  envs at most 2 / (its CPU per env step) env steps/s, whatever the scheduling. Then a node's loss and its recovery
  time: on a two-node cluster (workspace_tools.ray_cluster) with one actor on each node, the second node killed
  by PID as a machine lost, the wall time from the kill to the first env step of the actor Ray restarted on the
  head (worker_recovery); and the same for a sweep (cube only): from the kill to the lost trial's training
  resuming from its checkpoint on a free node (_sweep_recovery_time).
- sweeps: `./ws sweep cube` (workspace_tools.sweep, a private local Ray) of one trial against two trials
  run at once, each trial SWEEP_EPISODES cube training episodes and SWEEP_EVAL_EPISODES evaluation
  episodes; trials per hour of wall time, Ray's start and Tune's overhead included; the ratio two / one.

The Gazebo-style step is the tutorials' (robot_rl.backends.GazeboStyleBackend under a normal env): unpause,
publish the command, wait running_step of sim time (on /clock, throttled to 100 Hz of wall time as
gazebo_ros publishes it), pause, read the latest sensors. It is measured with the sim at
real_time_factor 1 and at 0 (as fast as possible).
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hopper_training.envs.stay_up import STAY_UP
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import TaskParams, TaskSpec, make_env
from workspace_tools.processes import Processes, RosMaster, launch_args

SECTIONS = ("lockstep", "scaling", "deep", "gazebo", "training", "distributed", "sweeps")
SWEEP_EPISODES, SWEEP_EVAL_EPISODES = 400, 5
PERFORMANCE_PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference" / "performance.md"
SCALING_ENVS = (1, 2, 4)
DISTRIBUTED_ENVS = (1, 2)
RECOVERY_STEPS_BEFORE_LOSS = 50  # vector steps of the two actors before the second node is killed


@dataclass(frozen=True)
class BenchRobot:
    task: TaskSpec[Any]               # the task the robot is measured on
    sim_seconds: float                # sim time per lockstep measurement (env steps = this / running_step)
    gazebo_steps: dict[float, int]    # Gazebo-style steps per real-time factor


ROBOTS = {"cube": BenchRobot(ONE_DISK_WALK, 180.0, {1.0: 20, 0.0: 50}),
          "hopper": BenchRobot(STAY_UP, 60.0, {1.0: 100, 0.0: 200})}
CEILING_WARNING = 1.5  # 2 independent direct processes below this speedup: the run did not have two free cores
DEEP_STEPS = 4000  # env steps of DQN learning (its first learning_starts only collect)


def _params(robot: str, running_step: float) -> TaskParams:
    """The robot's task params from its config, with the control period the bench measures."""
    params = ROBOTS[robot].task.default_params()
    return params if params.running_step == running_step else params.with_changes("bench", running_step=running_step)


# -- workers: each runs in its own process and prints one JSON line -------------------------------
def _make_env(robot: str, backend: Any, running_step: float):
    return make_env(ROBOTS[robot].task, params=_params(robot, running_step), backend=backend)


def _stat_fields(pid: int | str) -> list[str]:
    """A process's /proc/PID/stat after its name: [0] state, [1] parent PID, [11] user and [12] system CPU ticks."""
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()


def _cpu_s(fields: list[str]) -> float:
    """CPU seconds (user + system) from a process's _stat_fields."""
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _sim_node_pid() -> int:
    """The PID of the sim node on this process's master (from the node's own XML-RPC API)."""
    import xmlrpc.client

    import rosgraph
    import rospy
    uri = rosgraph.Master(rospy.get_name()).lookupNode("/pybullet_sim")
    answer: Any = xmlrpc.client.ServerProxy(uri).getPid(rospy.get_name())  # [code, status message, pid]
    return int(answer[2])


def lockstep_speedup_bound(step_times: Sequence[float], n: int = 2) -> float:
    """The most a vector env that steps n envs together can gain over one env with these step times: each
    of its steps lasts as long as the slowest of n, so n x mean / E[max of n] (the n steps drawn
    independently from these times; the expectation is exact over them)."""
    ordered, count = sorted(step_times), len(step_times)
    expected_max = sum(t * ((k / count) ** n - ((k - 1) / count) ** n) for k, t in enumerate(ordered, 1))
    return n * (sum(ordered) / count) / expected_max


def worker_lockstep(robot: str, backend: str, steps: int, running_step: float) -> dict:
    """One env, random actions: env steps/s, and where the CPU time of a step goes (microseconds per env step):
    over ROS this process (the task env and its service calls) and the sim node; direct the physics
    (World.step) and everything else (sensors and the task env); and lockstep_speedup_bound at N = 2."""
    import numpy as np
    if backend == "ros":
        import rospy
        rospy.init_node("bench_client")
    env = _make_env(robot, backend, running_step)
    physics_s = [0.0]
    if backend == "direct":
        world = env.unwrapped.backend.world
        world_step = world.step

        def timed_step(count: int = 1) -> None:
            start = time.thread_time()
            world_step(count)
            physics_s[0] += time.thread_time() - start
        world.step = timed_step
    sim_pid = _sim_node_pid() if backend == "ros" else None
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    physics_s[0] = 0.0
    wall_start, start, cpu_start = time.time(), time.perf_counter(), time.process_time()
    sim_start = _cpu_s(_stat_fields(sim_pid)) if sim_pid else 0.0
    step_times = []
    for _ in range(steps):
        step_start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(int(rng.integers(env.action_space.n)))
        if terminated or truncated:
            env.reset()
        step_times.append(time.perf_counter() - step_start)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    result = {"steps_per_s": steps / elapsed, "running_step": env.unwrapped.running_step,
              "wall_start": wall_start, "wall_end": wall_start + elapsed,
              "lockstep_speedup_bound_2": lockstep_speedup_bound(step_times)}
    if sim_pid:
        result["cpu_us_per_step"] = {"client": 1e6 * cpu / steps,
                                     "sim_node": 1e6 * (_cpu_s(_stat_fields(sim_pid)) - sim_start) / steps}
    else:
        result["cpu_us_per_step"] = {"physics": 1e6 * physics_s[0] / steps,
                                     "sensors_and_task": 1e6 * (cpu - physics_s[0]) / steps}
    env.close()
    return result


def _tree_cpu_s(cluster_mark: str = "") -> float:
    """CPU seconds used so far by this process and every process below it (workers, masters, sim nodes), and by
    every process of the LoopbackCluster whose mark is `cluster_mark` (its daemons, actors, their masters and sim
    nodes)."""
    from workspace_tools.launch_reaper import descendants, processes_with
    from workspace_tools.ray_cluster import MARK_VARIABLE
    cluster = processes_with(MARK_VARIABLE, cluster_mark) if cluster_mark else []
    total = 0.0
    for pid in {os.getpid(), *descendants(os.getpid()), *cluster}:
        try:
            total += _cpu_s(_stat_fields(pid))
        except OSError:  # gone
            continue
    return total


def worker_vector(robot: str, backend: str, n: int, steps: int, running_step: float, cluster: str = "",
                  cluster_mark: str = "") -> dict:
    """robot_rl.vector's gymnasium vector env of n workers (Ray actors on `cluster` if given): env steps/s (all
    workers together) and the CPU time per env step of every process involved (this one, the workers, their
    masters and sim nodes; with Ray actors, every process of the LoopbackCluster marked `cluster_mark`)."""
    import numpy as np

    from robot_rl import make_vector_env
    env = make_vector_env(ROBOTS[robot].task, n, backend=backend, seed=0, params=_params(robot, running_step),
                          cluster=cluster or None)
    try:
        rng = np.random.default_rng(0)
        n_actions = int(env.single_action_space.n)  # type: ignore[attr-defined]
        env.reset(seed=0)
        vector_steps = max(1, steps // n)
        start, cpu_start = time.perf_counter(), _tree_cpu_s(cluster_mark)
        for _ in range(vector_steps):
            env.step(rng.integers(n_actions, size=n))
        elapsed, cpu = time.perf_counter() - start, _tree_cpu_s(cluster_mark) - cpu_start
    finally:
        env.close()
    return {"steps_per_s": vector_steps * n / elapsed, "cpu_ms_per_step": 1000.0 * cpu / (vector_steps * n)}


def worker_recovery(robot: str, steps: int, running_step: float, folder: str) -> dict:
    """A node lost under a run: a two-node LoopbackCluster (the head 2 CPUs, the second 1) with a gymnasium vector
    env of 2 Ray actors, one on each node; after `steps` vector steps the second node is killed as a machine lost
    (every process of it, by PID), and the vector env steps on. Wall seconds from the kill to the first step the
    actor restarted on the head completes (Ray finds the node dead, restarts the actor, whose env starts a master
    and a sim node and resets; the vector env's step says WorkerRestarted, and the next step is the new actor's).
    Also the wall seconds the two actors took to start (each its master, sim node and env), for scale: the rest of
    the recovery is Ray finding the node dead (its health checks). RuntimeError if any process of the cluster is
    left after it ends."""
    import numpy as np

    from robot_rl import WorkerRestarted, make_vector_env
    from workspace_tools.ray_cluster import LoopbackCluster, process_name
    cluster = LoopbackCluster(Path(folder), nodes=2, cpus_per_node=1, head_cpus=2)
    try:
        cluster.connect()
        started = time.perf_counter()
        env = make_vector_env(ROBOTS[robot].task, 2, backend="ros", seed=0, params=_params(robot, running_step),
                              cluster=cluster.address)
        start = time.perf_counter() - started
        try:
            if len({worker["node_id"] for worker in env.workers.worker_info}) != 2:
                raise RuntimeError(f"the 2 actors were not placed one on each node: {env.workers.worker_info}")
            rng = np.random.default_rng(0)
            n_actions = int(env.single_action_space.n)  # type: ignore[attr-defined]
            env.reset(seed=0)
            for _ in range(steps):
                env.step(rng.integers(n_actions, size=2))
            killed = time.perf_counter()
            cluster.kill_node(1)
            try:
                env.step(rng.integers(n_actions, size=2))
            except WorkerRestarted:
                pass
            else:
                raise RuntimeError("the vector env stepped on after its second node was killed")
            env.step(rng.integers(n_actions, size=2))
            recovery = time.perf_counter() - killed
        finally:
            env.close()
    finally:
        left = cluster.close()
    if left:
        raise RuntimeError(f"processes of the cluster left after it ended: {[process_name(p) for p in left]}")
    return {"recovery_s": recovery, "start_s": start}


def worker_qlearn(robot: str, n: int, steps: int, running_step: float) -> dict:
    """robot_rl.vector_training's tabular Q-learning from n envs over ROS, as `./ws run envs:=N` trains
    (episodes.csv written) but with no log lines and no checkpoint until the end, which is not timed:
    env steps/s for `steps` env steps."""
    from robot_rl import RunDirectory, TrainingHooks, find_agent, make_vector_env
    task = ROBOTS[robot].task
    params = _params(robot, running_step).with_changes("bench", nepisodes=10**9)
    env: Any = make_vector_env(task, n, backend="ros", seed=0, params=params)  # the trainer takes it as its env
    taken, first, last = [0], [0.0], [0.0]

    def on_step(*_: Any) -> None:  # timed from the first transition learnt to the last (no start, no summary)
        last[0] = time.perf_counter()
        if not taken[0]:
            first[0] = last[0]
        taken[0] += 1
    try:
        with tempfile.TemporaryDirectory() as results:
            run = RunDirectory.create(Path(results), robot, params.to_mapping(), task.metric_names, "bench")
            hooks = TrainingHooks(log=lambda _: None, on_step=on_step, should_stop=lambda: taken[0] >= steps,
                                  checkpoint_every=10**9)
            find_agent("qlearn").make_trainer(env, task, params, run, hooks).train()  # N envs: the vector trainer
    finally:
        env.close()
    return {"steps_per_s": (taken[0] - 1) / (last[0] - first[0])}


def worker_deep(robot: str, backend: str, steps: int, running_step: float) -> dict:
    """Stable-Baselines3 DQN (robot_rl/config/dqn.yaml) learning `steps` env steps on one env."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    from robot_rl import NetworkParams, build_model, find_agent
    if backend == "ros":
        import rospy
        rospy.init_node("bench_deep_client")
    import torch
    torch.set_num_threads(1)  # as DeepTrainer
    params = _params(robot, running_step)
    env = _make_env(robot, backend, running_step)
    try:
        agent_params = find_agent("dqn").load_params()
        assert isinstance(agent_params, NetworkParams)
        model = build_model(agent_params, DummyVecEnv([lambda: env]), params.gamma, 0)
        start = time.perf_counter()
        model.learn(total_timesteps=steps)
        elapsed = time.perf_counter() - start
    finally:
        env.close()
    return {"steps_per_s": steps / elapsed}


def worker_gazebo_style(robot: str, steps: int, running_step: float) -> dict:
    """The tutorials' step over ROS (robot_rl.backends.GazeboStyleBackend: unpause, command, wait running_step
    of sim time on /clock, pause, read the latest sensors), one env, random actions: env steps/s."""
    import numpy as np
    import rospy

    from robot_rl import GazeboStyleBackend

    rospy.init_node("bench_gazebo_style_client")
    env = _make_env(robot, GazeboStyleBackend(ROBOTS[robot].task.robot), running_step)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    start = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(int(rng.integers(env.action_space.n)))
        if terminated or truncated:
            env.reset()
    elapsed = time.perf_counter() - start
    env.close()
    return {"steps_per_s": steps / elapsed}


# -- orchestration ------------------------------------------------------------------------------
def _run_worker(processes: Processes, args: list, timeout: float) -> dict:
    result = processes.run([sys.executable, __file__, "--worker", *map(str, args)], timeout=timeout)
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
        result = master.run(["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training", "main.launch",
                             *launch_args(results_dir=results, nepisodes=episodes, video="false")], timeout=900)
    finally:
        master.close()
    if result.returncode != 0:
        raise RuntimeError(f"cube training failed:\n{result.stdout[-3000:]}")
    return json.loads((results / "moving_cube" / "latest" / "summary.json").read_text())["wall_time_s"]


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
    sweep = folder / "results" / "moving_cube" / "lost"
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
                pid = int(_stat_fields(pid)[1])
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
    if "distributed" in sections:
        _distributed_rep(Path(f"{tag}-distributed"), rep, robot, steps, running_step, s)
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


def _row(rows: list[list[str]], report: dict, label: str, value: Any, fmt: str) -> None:
    """Append the row `label` with each robot's formatted value ("" where the report lacks it)."""
    cells = [label]
    for robot in ROBOTS:
        try:
            cells.append(fmt.format(value(report[robot])))
        except KeyError:
            cells.append("")
    rows.append(cells)


def _range_row(rows: list[list[str]], report: dict, label: str, key: str, scale: float = 1.0) -> None:
    """The lowest and highest repetition of a ratio, when there was more than one."""
    if report["repetitions"] > 1:
        _row(rows, report, f"  {label}: lowest-highest repetition",
             lambda r: "{:.2f}-{:.2f}".format(*(scale * f(r["per_repetition"][key]) for f in (min, max))), "{}")


def ceiling_warnings(report: dict) -> list[str]:
    """A line per robot whose two independent direct processes ran below CEILING_WARNING x one alone."""
    lines = []
    for robot in ROBOTS:
        speedup = report.get(robot, {}).get("scaling", {}).get("independent_direct_processes_speedup", {}).get("2")
        if speedup is not None and speedup < CEILING_WARNING:
            lines.append(f"{robot}: two independent direct processes ran only {speedup:.2f}x as fast as one: this run "
                         f"did not have two free cores, and its scaling figures are bounded by that")
    return lines


def table_rows(report: dict) -> list[list[str]]:
    """The table's rows that have a figure: a label, then each robot's cell ("" where the report lacks it); none
    when the run measured nothing per robot (only the training or sweeps sections)."""
    rows: list[list[str]] = []
    _row(rows, report, "running_step (s)", lambda r: r["running_step"], "{:g}")
    _row(rows, report, "one env over ROS (lockstep), env steps/s", lambda r: r["ros_lockstep_steps_per_s"], "{:.0f}")
    _row(rows, report, "one env direct (in-process), env steps/s", lambda r: r["direct_steps_per_s"], "{:.0f}")
    _row(rows, report, "ROS / direct", lambda r: r["ratio_ros_to_direct"], "{:.2f}")
    _range_row(rows, report, "ROS / direct", "ratio")
    _row(rows, report, "ROS lockstep x real time", lambda r: r["ros_lockstep_real_time_factor"], "{:.1f}")
    for backend, part, label in (("direct", "physics", "direct: physics (World.step)"),
                                 ("direct", "sensors_and_task", "direct: sensors, task env"),
                                 ("ros", "client", "ROS: client (task env, calls)"),
                                 ("ros", "sim_node", "ROS: sim node (physics, service)")):
        _row(rows, report, f"CPU us/env step, {label}", lambda r, b=backend, p=part: r["cpu_us_per_step"][b][p],
             "{:.0f}")
    for backend in ("ros", "direct"):
        _row(rows, report, f"N = 2 lockstep speedup bound, {backend} step times",
             lambda r, backend=backend: r["lockstep_speedup_bound"][backend]["2"], "{:.2f}")
        _range_row(rows, report, "bound", f"{backend}_lockstep_bound_2")
    for backend in ("ros", "direct"):
        for n in SCALING_ENVS:
            _row(rows, report, f"vector env, {backend}, N = {n}, env steps/s",
                 lambda r, backend=backend, n=n: r["scaling"][backend]["steps_per_s"][str(n)], "{:.0f}")
        for n in SCALING_ENVS:
            _row(rows, report, f"vector env, {backend}, N = {n}, CPU ms per env step",
                 lambda r, backend=backend, n=n: r["scaling"][backend]["cpu_ms_per_step"][str(n)], "{:.2f}")
        for n in SCALING_ENVS[1:]:
            _row(rows, report, f"vector env, {backend}, N = {n}: speedup over N = 1",
                 lambda r, backend=backend, n=n: r["scaling"][backend]["speedup"][str(n)], "{:.2f}")
            _range_row(rows, report, "speedup", f"{backend}_efficiency_{n}", scale=n)
            _row(rows, report, f"vector env, {backend}, N = {n}: parallel efficiency",
                 lambda r, backend=backend, n=n: r["scaling"][backend]["parallel_efficiency"][str(n)], "{:.2f}")
    for n in (1, 2):
        _row(rows, report, f"tabular Q-learning over ROS, N = {n}, env steps/s",
             lambda r, n=n: r["scaling"]["qlearn_ros"]["steps_per_s"][str(n)], "{:.0f}")
    _row(rows, report, "tabular Q-learning over ROS, N = 2: speedup",
         lambda r: r["scaling"]["qlearn_ros"]["speedup"]["2"], "{:.2f}")
    _range_row(rows, report, "speedup", "qlearn_speedup_2")
    _row(rows, report, "2 independent direct processes: speedup over 1",
         lambda r: r["scaling"]["independent_direct_processes_speedup"]["2"], "{:.2f}")
    _range_row(rows, report, "speedup", "independent_speedup_2")
    _row(rows, report, "DQN learning over ROS, env steps/s", lambda r: r["dqn"]["ros_steps_per_s"], "{:.0f}")
    _row(rows, report, "DQN learning direct, env steps/s", lambda r: r["dqn"]["direct_steps_per_s"], "{:.0f}")
    _row(rows, report, "DQN: ROS / direct", lambda r: r["dqn"]["ratio_ros_to_direct"], "{:.2f}")
    _range_row(rows, report, "DQN: ROS / direct", "deep_ratio")
    for n in DISTRIBUTED_ENVS:
        for transport, label in (("pipe", "pipe workers"), ("ray", "Ray actors")):
            _row(rows, report, f"vector env, ros, N = {n}, {label}, env steps/s",
                 lambda r, t=transport, n=n: r["distributed"]["steps_per_s"][t][str(n)], "{:.0f}")
        _row(rows, report, f"vector env, ros, N = {n}: Ray actors / pipe workers",
             lambda r, n=n: r["distributed"]["ratio_ray_to_pipe"][str(n)], "{:.2f}")
        _range_row(rows, report, "Ray / pipe", f"ray_to_pipe_{n}")
        for transport, label in (("pipe", "pipe workers"), ("ray", "Ray actors")):
            _row(rows, report, f"vector env, ros, N = {n}, {label}, CPU ms/step",
                 lambda r, t=transport, n=n: r["distributed"]["cpu_ms_per_step"][t][str(n)], "{:.2f}")
    _row(rows, report, "Ray actors, N = 2: start (masters, sims), s",
         lambda r: r["distributed"]["actors_start_s"], "{:.1f}")
    _row(rows, report, "node lost: its Ray actor steps again after, s",
         lambda r: r["distributed"]["node_loss_recovery_s"], "{:.1f}")
    _row(rows, report, "Gazebo-style step at RTF 1, steps/s", lambda r: r["gazebo_style_rtf1_steps_per_s"], "{:.1f}")
    _row(rows, report, "Gazebo-style step at max speed, steps/s", lambda r: r["gazebo_style_max_speed_steps_per_s"],
         "{:.1f}")
    figures = [row for row in rows[1:] if any(row[1:])]  # a section not run has no figures
    return [rows[0], *figures] if figures else []


def sweeps_line(sweeps: dict) -> str:
    """The sweeps section in one sentence."""
    per_hour = sweeps["trials_per_hour"]
    return (f"Sweeps (`./ws sweep cube`, {sweeps['episodes_per_trial']} training episodes a trial, Ray's start "
            f"included): one trial alone {per_hour['1']:.0f} trials/h, two at once {per_hour['2']:.0f} trials/h, "
            f"{sweeps['ratio_2_to_1']:.2f}x.")


def sweep_recovery_line(seconds: float) -> str:
    """A sweep's node loss in one sentence."""
    return (f"A node lost mid-sweep (`./ws sweep cube seeds:=0-1` on three one-CPU nodes, a trial on two of "
            f"them): the lost trial ran again on the free node, its training resumed from its checkpoint "
            f"{seconds:.1f} s after the kill.")


def print_table(report: dict) -> None:
    print(f"\n{report['machine']}\n{report['date']}, median of {report['repetitions']} repetitions, load average "
          f"{report['load_average_at_end']:.2f} at the end\n")
    rows = table_rows(report)
    if rows:
        print(f"| {'':52} | " + " | ".join(f"{robot:>9}" for robot in ROBOTS) + " |")
        print(f"|{'-' * 54}|" + "|".join("-" * 10 + ":" for _ in ROBOTS) + "|")
    for label, *cells in rows:
        print(f"| {label:52} | " + " | ".join(f"{cell:>9}" for cell in cells) + " |")
    if "cube_100_episodes_wall_s" in report:
        print(f"cube: 100 training episodes over ROS in {report['cube_100_episodes_wall_s']:.1f} s")
    if "sweep_node_loss_recovery_s" in report:
        print(sweep_recovery_line(report["sweep_node_loss_recovery_s"]))
    if "sweeps" in report:
        print(sweeps_line(report["sweeps"]))
    for line in ceiling_warnings(report):
        print(f"\nnote: {line}")


LOCKSTEP_FAST = """\
- An env step over ROS is one call of `/pybullet_sim/step_packed` on a persistent service connection: it
  carries the commands and answers with the readings, so no topic round trip is waited for.
- The answer is every sensor's values packed as numbers (`pybullet_sim/PackedReadings`), in a service type
  with nothing else in it: no message per sensor to build, serialise and parse.
- The sim node publishes synchronously (`queue_size=None`), builds a sensor message only for a topic with
  a subscriber, and throttles `/clock` to 100 Hz of wall time as gazebo_ros does.
- Sensors are read without numpy on the hot path, training runs no robot_state_publisher, and the PID
  loop makes no per-step lookups.
- The first physics steps after a reset are replayed from memory once the same start has been seen
  (`World.replay_from_reset`), bit for bit the stepped ones: the cube's landing after each reset costs
  microseconds instead of about 2.5 env steps.
- Vector env workers, and the master and sim node each starts, run in Linux's `SCHED_BATCH` class, whose
  wake-ups never preempt: the parent writes every worker its action before any worker takes its CPU.
- What is left over ROS is rospy's call (about 0.1 ms a step) and the sim node's own work around the
  physics; the machines of this pool differ by up to 2x, so compare ratios within one run.
"""


def markdown(report: dict, command: str) -> str:
    """docs/reference/performance.md from a report: how and where it was measured, the table (if the run measured
    anything per robot), a note when the machine was loaded, and (with the lockstep section) what made lockstep fast."""
    date = datetime.datetime.fromisoformat(report["date"]).astimezone(datetime.UTC)
    reps = report["repetitions"]
    lines = ["# Performance", "", f"Written by `{command}` on {date:%Y-%m-%d %H:%M} UTC.", "",
             f"Machine: {report['machine']}; load average {report['load_average_at_end']:.2f} at the end.", "",
             f"Every figure is the median of {reps} repetition{'s' if reps > 1 else ''}, each in fresh processes (a "
             f"new master, sim node and client), with random actions and episode resets included. Regenerate this "
             f"page with `./ws bench --markdown`."]
    rows = table_rows(report)
    if rows:
        lines += ["", "| | " + " | ".join(ROBOTS) + " |", "|---|" + "---:|" * len(ROBOTS)]
        lines += ["| " + " | ".join([label.strip(), *cells]) + " |" for label, *cells in rows]
    if "cube_100_episodes_wall_s" in report:
        lines += ["", f"100 episodes of cube training over ROS took {report['cube_100_episodes_wall_s']:.1f} s."]
    if "sweep_node_loss_recovery_s" in report:
        lines += ["", sweep_recovery_line(report["sweep_node_loss_recovery_s"])]
    if "sweeps" in report:
        lines += ["", sweeps_line(report["sweeps"])]
    warnings = ceiling_warnings(report)
    if warnings:
        lines += ["", "Note: the machine was loaded during this run, so its figures are lower than on two free "
                      "cores:", *(f"- {line}" for line in warnings)]
    elif "scaling" not in report.get("sections", ["scaling"]):
        lines += ["", "Note: this run had no scaling section, whose two independent processes tell whether the "
                      "machine had two free cores."]
    if "lockstep" in report.get("sections", SECTIONS):
        lines += ["", "## What made lockstep fast", "", LOCKSTEP_FAST.rstrip("\n")]
    return "\n".join(lines) + "\n"


def _running_step(text: str) -> tuple[str, float]:
    robot, _, value = text.partition("=")
    try:
        seconds = float(value)
    except ValueError:
        seconds = math.nan
    if robot not in ROBOTS or not seconds > 0.0:
        raise argparse.ArgumentTypeError(f"{text!r} is not ROBOT=SECONDS with ROBOT one of {', '.join(ROBOTS)}, "
                                         f"e.g. hopper=0.02")
    return robot, seconds


def _sections(text: str) -> set[str]:
    chosen = set(text.split(","))
    if not chosen <= set(SECTIONS):
        raise argparse.ArgumentTypeError(f"unknown section(s) {', '.join(sorted(chosen - set(SECTIONS)))} "
                                         f"(known: {', '.join(SECTIONS)})")
    return chosen


def main(argv) -> int:
    if argv and argv[0] == "--worker":
        kind, robot, *rest = argv[1:]
        if kind == "lockstep":
            result = worker_lockstep(robot, rest[0], int(rest[1]), float(rest[2]))
        elif kind == "vector":
            result = worker_vector(robot, rest[0], int(rest[1]), int(rest[2]), float(rest[3]), *rest[4:])
        elif kind == "recovery":
            result = worker_recovery(robot, int(rest[0]), float(rest[1]), rest[2])
        elif kind == "qlearn":
            result = worker_qlearn(robot, int(rest[0]), int(rest[1]), float(rest[2]))
        elif kind == "deep":
            result = worker_deep(robot, rest[0], int(rest[1]), float(rest[2]))
        else:
            result = worker_gazebo_style(robot, int(rest[0]), float(rest[1]))
        print(json.dumps(result))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=3, help="repetitions (fresh processes each); figures are medians")
    parser.add_argument("--output", type=Path, default=Path("bench_results.json"))
    parser.add_argument("--running-step", type=_running_step, action="append", default=[], metavar="ROBOT=S",
                        help="measure ROBOT at this control period instead of its config's (e.g. hopper=0.02)")
    parser.add_argument("--sections", type=_sections, default=set(SECTIONS),
                        help=f"comma-separated, of {', '.join(SECTIONS)} (default: all)")
    parser.add_argument("--markdown", nargs="?", type=Path, const=PERFORMANCE_PAGE, metavar="PATH",
                        help=f"also write the table as a page (default: {PERFORMANCE_PAGE})")
    args = parser.parse_args(argv)
    if args.reps < 1:
        parser.error("--reps must be >= 1")
    running_steps = {robot: spec.task.default_params().running_step for robot, spec in ROBOTS.items()}
    running_steps.update(dict(args.running_step))
    report = orchestrate(args.reps, args.output, running_steps, args.sections)
    print_table(report)
    print(f"\nwritten: {args.output}")
    if args.markdown:
        args.markdown.write_text(markdown(report, " ".join(["./ws bench", *argv])))
        print(f"written: {args.markdown}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
