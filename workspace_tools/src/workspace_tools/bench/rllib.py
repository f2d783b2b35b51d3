"""./ws bench's rllib section: agent rllib_ppo (RLlib's PPO, env runners on a private Ray) against Stable-Baselines3's
PPO on pipe workers (agent ppo's vector env), on the cube's task, direct backend, at equal settings.

Both train RLLIB_STEPS env steps with the generic configs (robot_rl/config/rllib_ppo.yaml and ppo.yaml, whose values
are the same) but RLLIB_FRAGMENT env steps per env per update (rollout_fragment_length = n_steps), so that a
configuration takes well under a minute; N = 1 and 2 envs (env runners, pipe workers), and at N = 2 RLlib again with
both envs in one runner (envs_per_runner 2: one batched forward pass for both, the "batched" figures). Timed: the
training loop only (RLlib's Algorithm.train() calls, SB3's learn()), Ray's start and the runners' envs made before.
Then sampling alone: one fragment of every runner (EnvRunner.sample, the policy acting) against SB3's vector env
stepped with the model's actions (policy.predict), RLLIB_FRAGMENT vector steps.

Where the RLlib run's CPU goes, from /proc (every thread of the driver and of every process below it: the private
Ray's GCS, raylet, its other daemons and idle workers, the env runners), counted from the first train() to the last:
- runner_main: the env runners' main threads, which run sample(): the env, torch inference, RLlib's connectors (and
  the Ray task's own dispatch in that thread, which cannot be told apart from here);
- driver_main: the driver's main thread: the learner's update (torch), RLlib's orchestration, and the Ray API calls
  made from it (serialising, ray.get);
- ray: what is Ray's own beyond doubt: the GCS, the raylet, Ray's other processes (dashboard agent, log monitor,
  idle workers) and every thread other than the main one of the driver and of the runners (Ray's core worker:
  gRPC, its event loops).
Ray's share = ray / total. It is a lower bound: Ray's work inside the two main threads is not in it (driver_main is
its upper bound's rest). And in sampling alone, the wall time Ray adds to one call of every runner's sample(): the
driver's wall time of the call less the slowest runner's own time in sample() (sample_call_ray_ms).

    python -m workspace_tools.bench.rllib rllib|batched|sb3 N STEPS RUNNING_STEP   (run by bench.orchestrate)
"""
from __future__ import annotations

import dataclasses
import json
import os
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

from workspace_tools.bench.common import ROBOTS, bench_params, cpu_seconds, stat_fields

RLLIB_ENVS = (1, 2)
RLLIB_STEPS = 8192    # env steps of training per configuration (all envs together): 16 updates at N = 2
RLLIB_FRAGMENT = 256  # env steps per env per update: RLlib's rollout_fragment_length, SB3's n_steps
RLLIB_BATCHED = (2,)  # N at which RLlib runs again with its N envs in one runner (envs_per_runner N)
ROBOT = "cube"
CPU_PARTS = ("runner_main", "driver_main", "ray")


def _thread_cpu(runner_pids: set[int]) -> dict[tuple[str, int, int], float]:
    """CPU seconds of every thread of this process and of every process below it, by (part, pid, tid)."""
    from workspace_tools.launch_reaper import descendants
    me = os.getpid()
    cpu: dict[tuple[str, int, int], float] = {}
    for pid in {me, *descendants(me)}:
        try:
            tids = [int(t) for t in os.listdir(f"/proc/{pid}/task")]
        except OSError:  # gone
            continue
        for tid in tids:
            main = "driver_main" if pid == me else "runner_main" if pid in runner_pids else "ray"
            part = main if tid == pid else "ray"
            try:
                cpu[part, pid, tid] = cpu_seconds(stat_fields(f"{pid}/task/{tid}"))
            except OSError:
                continue
    return cpu


def _cpu_split(before: dict, after: dict) -> dict[str, float]:
    """CPU seconds by part between two _thread_cpu snapshots (a thread started in between counts from 0)."""
    parts: dict[str, float] = defaultdict(float)
    for key, seconds in after.items():
        parts[key[0]] += seconds - before.get(key, 0.0)
    return {part: parts[part] for part in CPU_PARTS}


def _timed_sample(runner: Any) -> tuple[int, float]:
    """On a runner: one fragment of RLLIB_FRAGMENT env steps of each of its envs (sample()), and the wall seconds it
    took there."""
    start = time.perf_counter()
    episodes = runner.sample(num_timesteps=RLLIB_FRAGMENT * runner.num_envs)
    return sum(len(episode) for episode in episodes), time.perf_counter() - start


def worker_rllib(n: int, steps: int, running_step: float, envs_per_runner: int = 1) -> dict:
    """Agent rllib_ppo's training on n envs (n / envs_per_runner env runners, a private local Ray): env steps/s of
    Algorithm.train() calls until `steps` env steps, the CPU split of that time (module docstring), then sampling
    alone."""
    from robot_rl import DEFAULT_HOOKS, RunDirectory, find_agent
    agent = find_agent("rllib_ppo")
    task, params = ROBOTS[ROBOT].task, bench_params(ROBOT, running_step)
    agent_params = dataclasses.replace(agent.load_params(), rollout_fragment_length=RLLIB_FRAGMENT,  # type: ignore
                                       envs_per_runner=envs_per_runner)
    envs = agent.make_vector_env(task, n, "direct", 0, params, 10.0)  # Ray is set up and started here
    from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED  # only now: Ray reads its token
    try:
        with tempfile.TemporaryDirectory(prefix="bench-rllib-") as folder:
            run = RunDirectory(folder, agent.checkpoint_name)
            trainer: Any = agent.make_trainer(envs, task, params, run, DEFAULT_HOOKS, agent_params=agent_params,
                                              max_steps=steps)
            algorithm = trainer.algorithm
            runners = {pid for _, _, pid in envs.runner_info()}
            done, before = 0, _thread_cpu(runners)
            start = time.perf_counter()
            while done < steps:
                done += int(algorithm.train()[ENV_RUNNER_RESULTS][NUM_ENV_STEPS_SAMPLED])
            elapsed = time.perf_counter() - start
            cpu = _cpu_split(before, _thread_cpu(runners))
            sample_start = time.perf_counter()
            sampled = algorithm.env_runner_group.foreach_env_runner(_timed_sample, local_env_runner=False)
            sample_elapsed = time.perf_counter() - sample_start
    finally:
        envs.close()
    total = sum(cpu.values())
    return {"steps_per_s": done / elapsed, "steps": done,
            "cpu_ms_per_step": {part: 1000.0 * seconds / done for part, seconds in cpu.items()},
            "ray_cpu_share": cpu["ray"] / total,
            "sample_steps_per_s": sum(steps for steps, _ in sampled) / sample_elapsed,
            "sample_call_ray_ms": 1000.0 * (sample_elapsed - max(own for _, own in sampled))}


def worker_sb3(n: int, steps: int, running_step: float) -> dict:
    """Stable-Baselines3 PPO (agent ppo's params, n_steps RLLIB_FRAGMENT) on agent ppo's vector env of n pipe
    workers, direct: env steps/s of learn(steps) and its CPU per env step (every process), then sampling alone."""
    import torch

    from robot_rl import build_model, find_agent
    from workspace_tools.launch_reaper import descendants
    torch.set_num_threads(1)  # as DeepTrainer
    agent = find_agent("ppo")
    task, params = ROBOTS[ROBOT].task, bench_params(ROBOT, running_step)
    agent_params = dataclasses.replace(agent.load_params(), n_steps=RLLIB_FRAGMENT)  # type: ignore[type-var]
    env = agent.make_vector_env(task, n, "direct", 0, params, 10.0)

    def tree_cpu() -> float:
        total = 0.0
        for pid in {os.getpid(), *descendants(os.getpid())}:
            try:
                total += cpu_seconds(stat_fields(pid))
            except OSError:
                continue
        return total
    try:
        model = build_model(agent_params, env, params.gamma, 0)  # type: ignore[arg-type]
        start, cpu_start = time.perf_counter(), tree_cpu()
        model.learn(total_timesteps=steps)
        elapsed, cpu = time.perf_counter() - start, tree_cpu() - cpu_start
        done = model.num_timesteps
        observations = env.reset()
        sample_start = time.perf_counter()
        for _ in range(RLLIB_FRAGMENT):
            actions, _ = model.predict(observations)
            observations, *_ = env.step(actions)
        sample_elapsed = time.perf_counter() - sample_start
    finally:
        env.close()
    return {"steps_per_s": done / elapsed, "steps": done, "cpu_ms_per_step_total": 1000.0 * cpu / done,
            "sample_steps_per_s": RLLIB_FRAGMENT * n / sample_elapsed}


def sync_bound(runner_ms: float, driver_ms: float, runners: int) -> float:
    """The most env steps/s synchronous PPO can train at, from its CPU ms per env step: `runners` runners (at most
    one per core) sample in parallel, then the learner on the driver updates while they wait, so each env step
    takes at least runner_ms / runners + driver_ms of wall time (runner_ms: all runners' together)."""
    return 1000.0 / (runner_ms / runners + driver_ms)


def rllib_rep(run_worker: Callable[[Path, list], dict], folder: Path, rep: int, running_step: float, s: dict,
              log: Callable[[str], None]) -> None:
    """One repetition: RLlib and SB3 at N = 1 and 2 (and RLlib batched at RLLIB_BATCHED), interleaved, each in a
    fresh process (run_worker(log folder, args)); into the cube's samples `s`."""
    for n in RLLIB_ENVS:
        for kind in ("rllib", "sb3", *(("batched",) if n in RLLIB_BATCHED else ())):
            result = run_worker(folder / f"{kind}-{n}", ["workspace_tools.bench.rllib", kind, n, RLLIB_STEPS,
                                                         running_step])
            s[f"rllib_{kind}_{n}"].append(result["steps_per_s"])
            s[f"rllib_{kind}_sample_{n}"].append(result["sample_steps_per_s"])
            if kind == "batched":
                s[f"rllib_batched_cpu_runner_main_{n}"].append(result["cpu_ms_per_step"]["runner_main"])
                s[f"rllib_batched_ray_share_{n}"].append(result["ray_cpu_share"])
            elif kind == "rllib":
                for part, value in result["cpu_ms_per_step"].items():
                    s[f"rllib_cpu_{part}_{n}"].append(value)
                s[f"rllib_ray_share_{n}"].append(result["ray_cpu_share"])
                s[f"rllib_sample_call_ray_ms_{n}"].append(result["sample_call_ray_ms"])
            else:
                s[f"rllib_sb3_cpu_{n}"].append(result["cpu_ms_per_step_total"])
        s[f"rllib_ratio_{n}"].append(s[f"rllib_rllib_{n}"][-1] / s[f"rllib_sb3_{n}"][-1])
        s[f"rllib_bound_ratio_{n}"].append(sync_bound(s[f"rllib_cpu_runner_main_{n}"][-1],
                                                      s[f"rllib_cpu_driver_main_{n}"][-1], n)
                                           / s[f"rllib_sb3_{n}"][-1])
        log(f"rep {rep + 1} cube: RLlib PPO / SB3 PPO (pipe), N={n}: {s[f'rllib_rllib_{n}'][-1]:.0f}/"
            f"{s[f'rllib_sb3_{n}'][-1]:.0f} env steps/s = {s[f'rllib_ratio_{n}'][-1]:.2f}; Ray's CPU share "
            f"{s[f'rllib_ray_share_{n}'][-1]:.3f}")
        if n in RLLIB_BATCHED:
            s[f"rllib_batched_ratio_{n}"].append(s[f"rllib_batched_{n}"][-1] / s[f"rllib_sb3_{n}"][-1])
            log(f"rep {rep + 1} cube: RLlib PPO with its {n} envs in 1 runner / SB3 PPO (pipe): "
                f"{s[f'rllib_batched_{n}'][-1]:.0f}/{s[f'rllib_sb3_{n}'][-1]:.0f} env steps/s = "
                f"{s[f'rllib_batched_ratio_{n}'][-1]:.2f}")


def rllib_summary(s: dict, median: Callable[[list], float]) -> dict:
    """The section's figures in the report (the medians of the repetitions)."""
    def by_n(key: str) -> dict[str, float]:
        return {str(n): median(s[f"{key}_{n}"]) for n in RLLIB_ENVS}
    return {"steps": RLLIB_STEPS, "fragment": RLLIB_FRAGMENT, "envs": list(RLLIB_ENVS),
            "steps_per_s": {"rllib": by_n("rllib_rllib"), "sb3_pipe": by_n("rllib_sb3")},
            "ratio_rllib_to_sb3": by_n("rllib_ratio"),
            "bound_ratio_rllib_to_sb3": by_n("rllib_bound_ratio"),
            "rllib_cpu_ms_per_step": {part: by_n(f"rllib_cpu_{part}") for part in CPU_PARTS},
            "sb3_cpu_ms_per_step": by_n("rllib_sb3_cpu"),
            "ray_cpu_share": by_n("rllib_ray_share"),
            "sample_steps_per_s": {"rllib": by_n("rllib_rllib_sample"), "sb3_pipe": by_n("rllib_sb3_sample")},
            "sample_call_ray_ms": by_n("rllib_sample_call_ray_ms"),
            "batched": {str(n): {"steps_per_s": median(s[f"rllib_batched_{n}"]),
                                 "ratio_to_sb3": median(s[f"rllib_batched_ratio_{n}"]),
                                 "runner_cpu_ms_per_step": median(s[f"rllib_batched_cpu_runner_main_{n}"]),
                                 "ray_cpu_share": median(s[f"rllib_batched_ray_share_{n}"]),
                                 "sample_steps_per_s": median(s[f"rllib_batched_sample_{n}"])}
                        for n in RLLIB_BATCHED}}


def _figure(*keys: str) -> Callable[[dict], Any]:
    """The figure at r["rllib"][keys...] of a robot's report `r` (KeyError where it has none)."""
    def figure(r: dict) -> Any:
        value = r["rllib"]
        for key in keys:
            value = value[key]
        return value
    return figure


def rllib_rows() -> list[tuple[str, Callable[[dict], Any], str, str, str]]:
    """The section's table rows: (label, the figure from a robot's report, its format, and for a ratio its
    lowest-highest row's label and per_repetition key, else "", "")."""
    rows: list[tuple[str, Callable[[dict], Any], str, str, str]] = []
    for n in map(str, RLLIB_ENVS):
        for kind, label in (("rllib", f"RLlib PPO, N = {n} runners"), ("sb3_pipe", f"SB3 PPO, N = {n} pipe workers")):
            rows.append((f"{label}, train env steps/s", _figure("steps_per_s", kind, n), "{:.0f}", "", ""))
        rows.append((f"RLlib / SB3 PPO training, N = {n}", _figure("ratio_rllib_to_sb3", n), "{:.2f}", "RLlib / SB3",
                     f"rllib_ratio_{n}"))
        rows.append((f"RLlib / SB3 PPO training, N = {n}, at most (sync_bound: runners' CPU / N + learner's)",
                     _figure("bound_ratio_rllib_to_sb3", n), "{:.2f}", "", ""))
        for part, label in (("runner_main", "runners' sample()"), ("driver_main", "driver (learner)"),
                            ("ray", "Ray's own")):
            rows.append((f"RLlib, N = {n}, CPU ms/env step: {label}", _figure("rllib_cpu_ms_per_step", part, n),
                         "{:.2f}", "", ""))
        rows.append((f"SB3, N = {n}, CPU ms/env step: all processes", _figure("sb3_cpu_ms_per_step", n), "{:.2f}",
                     "", ""))
        rows.append((f"RLlib, N = {n}: Ray's CPU share", _figure("ray_cpu_share", n), "{:.3f}", "Ray's share",
                     f"rllib_ray_share_{n}"))
        for kind, label in (("rllib", "RLlib runners"), ("sb3_pipe", "SB3 vec env")):
            rows.append((f"sampling only, N = {n}, {label}, env steps/s", _figure("sample_steps_per_s", kind, n),
                         "{:.0f}", "", ""))
        rows.append((f"sampling only, N = {n}: Ray's wall per sample call, ms", _figure("sample_call_ray_ms", n),
                     "{:.1f}", "", ""))
        if int(n) in RLLIB_BATCHED:
            label = f"RLlib, N = {n} envs in 1 runner (envs_per_runner {n})"
            rows += [(f"{label}, train env steps/s", _figure("batched", n, "steps_per_s"), "{:.0f}", "", ""),
                     (f"{label} / SB3 PPO training", _figure("batched", n, "ratio_to_sb3"), "{:.2f}",
                      "batched / SB3", f"rllib_batched_ratio_{n}"),
                     (f"{label}, CPU ms/env step: runner's sample()", _figure("batched", n, "runner_cpu_ms_per_step"),
                      "{:.2f}", "", ""),
                     (f"{label}: Ray's CPU share", _figure("batched", n, "ray_cpu_share"), "{:.3f}", "", ""),
                     (f"sampling only, {label}, env steps/s", _figure("batched", n, "sample_steps_per_s"), "{:.0f}",
                      "", "")]
    return rows


def main(argv: list[str]) -> int:
    """Run the worker KIND (argv: rllib|batched|sb3 N STEPS RUNNING_STEP) and print its result as one JSON line."""
    kind, n, steps, running_step = argv
    if kind == "sb3":
        result = worker_sb3(int(n), int(steps), float(running_step))
    else:
        result = worker_rllib(int(n), int(steps), float(running_step), int(n) if kind == "batched" else 1)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
