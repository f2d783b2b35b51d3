"""./ws bench's workers: each measurement runs in a process of its own and prints one JSON line.

  python -m workspace_tools.bench.workers KIND ROBOT ARGS...   (run by workspace_tools.bench.orchestrate)
"""
from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from robot_rl import make_env
from workspace_tools.bench.common import (
    BC_DAGGER_TINY,
    ROBOTS,
    bench_params,
    cpu_seconds,
    lockstep_speedup_bound,
    stat_fields,
)


def _make_env(robot: str, backend: Any, running_step: float):
    return make_env(ROBOTS[robot].task, params=bench_params(robot, running_step), backend=backend)


def _sim_node_pid() -> int:
    """The PID of the sim node on this process's master (from the node's own XML-RPC API)."""
    import xmlrpc.client

    import rosgraph
    import rospy
    uri = rosgraph.Master(rospy.get_name()).lookupNode("/pybullet_sim")
    answer: Any = xmlrpc.client.ServerProxy(uri).getPid(rospy.get_name())  # [code, status message, pid]
    return int(answer[2])


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
    sim_start = cpu_seconds(stat_fields(sim_pid)) if sim_pid else 0.0
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
                                     "sim_node": 1e6 * (cpu_seconds(stat_fields(sim_pid)) - sim_start) / steps}
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
            total += cpu_seconds(stat_fields(pid))
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
    env = make_vector_env(ROBOTS[robot].task, n, backend=backend, seed=0, params=bench_params(robot, running_step),
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
        env = make_vector_env(ROBOTS[robot].task, 2, backend="ros", seed=0, params=bench_params(robot, running_step),
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
    params = bench_params(robot, running_step).with_changes("bench", nepisodes=10**9)
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
    params = bench_params(robot, running_step)
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


def worker_end_to_end(backend: str, steps: int) -> dict:
    """The hopper's end_to_end task (MonopedEndToEnd-v0, its config's 5 ms) on one env, the teacher (the hopping
    controller, shadow-run as bc_dagger's teacher.py) acting, as in behaviour cloning: env steps/s of the env's
    own time (its step and reset calls; the controller's time per step is left out, and given apart)."""
    from hopper_training.envs.end_to_end import END_TO_END
    from hopper_training.teacher.teacher import Teacher
    if backend == "ros":
        import rospy
        rospy.init_node("bench_end_to_end_client")
    env = make_env(END_TO_END, backend=backend, seed=0)
    try:
        teacher = Teacher(env)
        env_s = teacher_s = 0.0
        start = time.perf_counter()
        observation, _ = env.reset(seed=0)
        teacher.reset()
        env_s += time.perf_counter() - start
        episodes = 1
        for _ in range(steps):
            start = time.perf_counter()
            action = teacher.label(observation)
            middle = time.perf_counter()
            observation, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                observation, _ = env.reset()
                teacher.reset()
                episodes += 1
            end = time.perf_counter()
            teacher_s, env_s = teacher_s + middle - start, env_s + end - middle
    finally:
        env.close()
    return {"steps_per_s": steps / env_s, "teacher_us_per_step": 1e6 * teacher_s / steps, "episodes": episodes}


def worker_bc_dagger() -> dict:
    """Agent bc_dagger (hopper_training/teacher) training on the direct backend on a tiny budget (BC_DAGGER_TINY):
    its samples (env steps collected and labelled) per second of wall time, collection and fitting included."""
    from hopper_training.envs.end_to_end import END_TO_END
    from robot_rl import RunDirectory, TrainingHooks, find_agent
    agent = find_agent("bc_dagger")
    params = END_TO_END.default_params()
    env = make_env(END_TO_END, params=params, backend="direct", seed=0)
    try:
        with tempfile.TemporaryDirectory() as results:
            run = RunDirectory.create(Path(results), agent.results_name(END_TO_END), params.to_mapping(),
                                      END_TO_END.metric_names, "bench", checkpoint_name=agent.checkpoint_name)
            agent_params = agent.load_params()
            assert agent_params is not None
            trainer = agent.make_trainer(env, END_TO_END, params, run, TrainingHooks(log=lambda _: None),
                                         agent_params=agent_params.with_changes("bench", **BC_DAGGER_TINY))
            start = time.perf_counter()
            summary = trainer.train()
            elapsed = time.perf_counter() - start
    finally:
        env.close()
    samples = summary["rounds"][-1]["samples"]
    fitting = sum(r["train_wall_s"] for r in summary["rounds"])
    return {"samples_per_s": samples / elapsed, "samples": samples, "wall_s": elapsed, "fit_s": fitting}


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



def main(argv: list[str]) -> int:
    """Run the worker KIND (argv: KIND ROBOT ARGS...) and print its result as one JSON line."""
    kind, robot, *rest = argv
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
    elif kind == "end_to_end":
        result = worker_end_to_end(rest[0], int(rest[1]))
    elif kind == "bc_dagger":
        result = worker_bc_dagger()
    else:
        result = worker_gazebo_style(robot, int(rest[0]), float(rest[1]))
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
