"""The round trip of a trivial Ray actor method, the floor under an env step over Ray actors.

For 1 and 2 actors on a LoopbackCluster of this machine (--nodes 2: each actor on a node of its own; 1: both on
the driver's node): plain `.remote` calls taken as robot_rl.ray_workers takes a step (a bounded ray.wait for all,
then ray.get), the same with ray.get(timeout=...), one Ray Compiled Graph over all the actors (InputNode,
MultiOutputNode, experimental_compile), a threaded actor (max_concurrency=2) and an async actor; and a pipe to a
spawned process for scale. Each call sends an int and answers an observation-sized numpy array (and, for
Ray's floor, a sync actor's method that answers None). Prints
microseconds per round trip (the median of --reps blocks of --calls calls), with the date, the machine and its
load average, and the CPU time every process involved spent per round trip (this one, its children and every
process of the cluster, from each thread's /proc schedstat: CPU time, which other jobs on the machine change
less than wall time). Then the same with real envs (--env-steps): the cube's env steps/s at N = 2 over ROS with pipe
workers (robot_rl.vector), with Ray actors (robot_rl.ray_workers) and with one compiled graph over those
actors, and the CPU time per env step of every process of each (workers, masters, sim nodes, Ray's daemons).
From those CPU figures follows a bound that no scheduling can beat: on C idle cores, a way of stepping envs
makes at most C / (its CPU per env step) env steps/s.

    ./ws python workspace_tools/scripts/ray_call_bench.py [--nodes 1|2] [--calls 2000] [--reps 3] [--env-steps 1000]
        [--threads]
"""
from __future__ import annotations

import argparse
import datetime
import multiprocessing
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np


class Echo:
    """A trivial actor: answers an observation-sized array for any action."""

    def __init__(self) -> None:
        self.observation = np.zeros(8, dtype=np.float32)

    def step(self, action: Any) -> np.ndarray:
        self.observation[0] = float(action)
        return self.observation.copy()

    def nothing(self, action: Any) -> None:
        """Ray's floor: a call that sends an int and answers None."""


class AsyncEcho(Echo):
    """Echo whose method is a coroutine: Ray runs it on the actor's event loop instead of its main thread."""

    async def step(self, action: Any) -> np.ndarray:  # type: ignore[override]
        return Echo.step(self, action)


def _pipe_echo(conn: Any) -> None:
    echo = Echo()
    while True:
        action = conn.recv()
        if action is None:
            return
        conn.send(echo.step(action))


def _thread_cpu_ns(pids: list[int]) -> dict[tuple[int, str], int]:
    """CPU time spent so far by each thread of `pids` (ns, /proc/PID/task/TID/schedstat's first field), keyed by
    its pid and its tid and name."""
    found = {}
    for pid in pids:
        try:
            threads = os.listdir(f"/proc/{pid}/task")
        except OSError:  # gone
            continue
        for tid in threads:
            try:
                name = Path(f"/proc/{pid}/task/{tid}/comm").read_text().strip()
                found[(pid, f"{tid} {name}")] = int(Path(f"/proc/{pid}/task/{tid}/schedstat").read_text().split()[0])
            except (OSError, IndexError, ValueError):
                continue
    return found


def _cpu_ns(pids: list[int]) -> int:
    """CPU time spent so far by every thread of `pids` (ns)."""
    return sum(_thread_cpu_ns(pids).values())


def _per_thread(call: Any, calls: int, meter: CpuMeter) -> list[tuple[float, str, str]]:
    """CPU microseconds per call of each process and thread name that spent 5 us or more, most first."""
    for i in range(min(200, calls)):  # warm up
        call(i)
    meter.start()
    before = _thread_cpu_ns(meter.pids)
    for i in range(calls):
        call(i)
    spent: dict[tuple[str, str], float] = {}
    for (pid, thread), ns in _thread_cpu_ns(meter.pids).items():
        try:
            process = "this driver" if pid == os.getpid() else Path(f"/proc/{pid}/comm").read_text().strip()
        except OSError:  # gone since
            process = f"pid {pid}"
        key = (process, thread.split(" ", 1)[1])
        spent[key] = spent.get(key, 0.0) + (ns - before.get((pid, thread), 0)) / calls / 1e3
    return sorted(((us, *key) for key, us in spent.items() if us >= 5), reverse=True)


class CpuMeter:
    """CPU time per operation of this process, its descendants and `extra()`'s pids, found at start()."""

    def __init__(self, extra: Any = lambda: []) -> None:
        self.extra = extra
        self.pids: list[int] = []
        self.start_ns = 0

    def start(self) -> None:
        from workspace_tools.launch_reaper import descendants
        self.pids = sorted({os.getpid(), *descendants(os.getpid()), *self.extra()})
        self.start_ns = _cpu_ns(self.pids)

    def per(self, operations: int) -> float:
        """Microseconds of CPU per operation since start()."""
        return (_cpu_ns(self.pids) - self.start_ns) / operations / 1e3


def _timed(call: Any, calls: int, reps: int, meter: CpuMeter) -> tuple[float, float]:
    """Median microseconds per call over reps blocks of calls, and the CPU microseconds per call over them."""
    for i in range(min(200, calls)):  # warm up
        call(i)
    blocks = []
    meter.start()
    for _ in range(reps):
        start = time.perf_counter()
        for i in range(calls):
            call(i)
        blocks.append((time.perf_counter() - start) / calls * 1e6)
    return statistics.median(blocks), meter.per(reps * calls)


def _wait_get(ray: Any, refs: list[Any]) -> list[Any]:
    """As robot_rl.ray_workers takes every reply: a bounded ray.wait for all, then ray.get."""
    ray.wait(refs, num_returns=len(refs), timeout=10.0)
    return ray.get(refs)


def _env_rates(ray: Any, cluster: Any, steps: int) -> dict[str, tuple[float, float]]:
    """Env steps/s of the cube's vector env at N = 2 over ROS (random actions, resets included), and CPU
    microseconds per env step: pipe workers (this process and its descendants), Ray actors as
    robot_rl.ray_workers steps them, and one compiled graph over the same two actors (this process and every
    process of the cluster)."""
    from ray.dag import InputNode, MultiOutputNode

    from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
    from robot_rl import EnvWorkers, RayEnvWorkers

    def rate(step: Any, meter: CpuMeter) -> tuple[float, float]:
        rng = np.random.default_rng(0)
        for _ in range(min(50, steps)):  # warm up
            step([int(a) for a in rng.integers(5, size=2)])
        meter.start()
        start = time.perf_counter()
        for _ in range(steps):
            step([int(a) for a in rng.integers(5, size=2)])
        return 2 * steps / (time.perf_counter() - start), meter.per(2 * steps)
    rates = {}
    pipes = EnvWorkers(ONE_DISK_WALK, 2, seed=0)
    try:
        pipes.request_all("reset", [(seed, None) for seed in pipes.seeds])
        rates["pipe workers (EnvWorkers)"] = rate(lambda actions: pipes.request_all("step", actions), CpuMeter())
    finally:
        pipes.close()
    on_cluster = CpuMeter(cluster.processes)
    actors = RayEnvWorkers(ONE_DISK_WALK, 2, seed=0, cluster=cluster.address)
    try:
        actors.request_all("reset", [(seed, None) for seed in actors.seeds])
        rates["Ray actors (RayEnvWorkers)"] = rate(lambda actions: actors.request_all("step", actions), on_cluster)
        with InputNode() as command:
            dag = MultiOutputNode([actor.command.bind(command[0], command[i + 1])
                                   for i, actor in enumerate(actors._actors)])
        compiled = dag.experimental_compile()
        try:
            rates["the same actors, one compiled graph"] = rate(
                lambda actions: ray.get(compiled.execute("step", *actions), timeout=60.0), on_cluster)
        finally:
            compiled.teardown()
    finally:
        actors.close()
    return rates


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=2000)
    parser.add_argument("--reps", type=int, default=3)
    parser.add_argument("--nodes", type=int, default=2, choices=(1, 2),
                        help="2: each actor on a node of its own; 1: both on the driver's node")
    parser.add_argument("--env-steps", type=int, default=1000,
                        help="vector steps of the cube's real envs at N = 2 each way (0: none)")
    parser.add_argument("--threads", action="store_true",
                        help="also where the CPU of --calls calls to 1 actor answering None goes, per thread")
    args = parser.parse_args(argv)
    from workspace_tools.ray_cluster import LoopbackCluster
    figures: dict[str, tuple[float, float]] = {}
    threads: list[tuple[float, str, str]] = []  # microseconds per round trip: wall, CPU
    context = multiprocessing.get_context("spawn")
    parent, child = context.Pipe()
    process = context.Process(target=_pipe_echo, args=(child,), daemon=True)
    process.start()

    def pipe_call(i: int) -> None:
        parent.send(i)
        parent.recv()
    figures["pipe, 1 process"] = _timed(pipe_call, args.calls, args.reps, CpuMeter())
    parent.send(None)
    process.join()
    with tempfile.TemporaryDirectory(prefix="ray-call-bench-") as folder, \
            LoopbackCluster(Path(folder), nodes=args.nodes, cpus_per_node=3 - args.nodes) as cluster:
        cluster.connect()  # before ray is imported: Ray reads the token then
        import ray
        from ray.dag import InputNode, MultiOutputNode
        on_cluster = CpuMeter(cluster.processes)
        placed: dict[str, Any] = {"num_cpus": 1, "scheduling_strategy": "SPREAD"}
        kinds: dict[str, Any] = {"sync": ray.remote(Echo).options(**placed),  # as robot_rl.ray_workers' actors
                                 "threaded": ray.remote(Echo).options(max_concurrency=2, **placed),
                                 "async": ray.remote(AsyncEcho).options(**placed)}
        for kind, remote in kinds.items():
            actors = [remote.remote() for _ in range(2)]
            ray.get([actor.__ray_ready__.remote() for actor in actors], timeout=60.0)
            for n in (1, 2):
                chosen = actors[:n]
                figures[f"{n} actor(s), {kind}, .remote, wait + get"] = _timed(
                    lambda i, chosen=chosen: _wait_get(ray, [actor.step.remote(i) for actor in chosen]),
                    args.calls, args.reps, on_cluster)
                if kind != "sync":
                    continue
                figures[f"{n} actor(s), {kind}, .remote, wait + get, answers None"] = _timed(
                    lambda i, chosen=chosen: _wait_get(ray, [actor.nothing.remote(i) for actor in chosen]),
                    args.calls, args.reps, on_cluster)
                figures[f"{n} actor(s), {kind}, .remote, get(timeout)"] = _timed(
                    lambda i, chosen=chosen: ray.get([actor.step.remote(i) for actor in chosen], timeout=10.0),
                    args.calls, args.reps, on_cluster)
                with InputNode() as action:
                    dag = MultiOutputNode([actor.step.bind(action) for actor in chosen])
                compiled = dag.experimental_compile()
                try:
                    figures[f"{n} actor(s), {kind}, compiled graph"] = _timed(
                        lambda i, c=compiled: ray.get(c.execute(i), timeout=10.0), args.calls, args.reps,
                        on_cluster)
                finally:
                    compiled.teardown()
            if kind == "sync" and args.threads:
                threads = _per_thread(lambda i, actor=actors[0]: _wait_get(ray, [actor.nothing.remote(i)]),
                                      args.calls, on_cluster)
            for actor in actors:
                ray.kill(actor)
        env_rates = _env_rates(ray, cluster, args.env_steps) if args.env_steps else {}
    date = datetime.datetime.now(datetime.UTC)
    cores = os.cpu_count() or 1
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), "?")
    print(f"{date:%Y-%m-%d %H:%M} UTC, {cpu}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; "
          f"{args.nodes} Ray node(s) on this machine; median of {args.reps} x {args.calls} calls")
    for label, (wall, cpu_time) in figures.items():
        print(f"{label:58} {wall:6.0f} us per round trip, {cpu_time:6.0f} us CPU")
    for microseconds, owner, thread in threads:
        print(f"1 actor, answers None: {microseconds:5.0f} us CPU per call in {owner}'s thread {thread}")
    pipe_rate, pipe_cpu = next(iter(env_rates.values()), (0.0, 0.0))
    for label, (rate, cpu_time) in env_rates.items():
        print(f"cube, N = 2, {label:45} {rate:6.0f} env steps/s, {rate / pipe_rate:.2f}x pipe; {cpu_time:5.0f} us "
              f"CPU per env step ({cpu_time / pipe_cpu:.2f}x pipe): at most {cores / cpu_time * 1e6:5.0f} env "
              f"steps/s on {cores} idle cores")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
