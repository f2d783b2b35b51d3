"""Where an RLlib env runner's time goes per env step, and the learner's per env step (agent rllib_ppo, direct backend).

One env runner (--envs N: N / --envs-per-runner of them) on a private local Ray, as agent rllib_ppo makes them
(robot_rl's agent registry), a few PPO updates as warm-up and to time the learner, then on runner 1, inside its
process, --fragments calls of sample(num_timesteps=--fragment) timed by parts with the main thread's CPU clock
(time.thread_time, a wrapper around each part; nested parts are subtracted from the enclosing one), then as many
calls again sampled from outside by py-spy (`pip install py-spy`; --rate samples/s of the runner's process, raw
stacks), for the detail: the stacks' shares by the same parts, and the functions most often on top. py-spy samples
from outside the process, at a cost that does not grow with the number of Python calls (cProfile's does, and
inflates the Python-heavy parts: RLlib's connectors); without py-spy only the timed parts are reported.

The parts, per env step (CPU ms of the runner's main thread):
- physics: pybullet.stepSimulation;
- our env: the task env and EpisodeTap (robot_rl.agents.rllib.runners) less the physics;
- gymnasium vector env: RLlib's vector env around our env (SyncVectorEnv, DictInfoToList) and its _try_env_step;
- env-to-module and module-to-env: RLlib's two connector pipelines;
- torch forward: the RLModule's forward_exploration (the policy's and the value's MLPs, no grad);
- episode bookkeeping: SingleAgentEpisode's add_env_reset/add_env_step/cut/validate/to_numpy, the episode callbacks
  and new episodes, the sampled-metrics logging;
- rest of sample(): RLlib's loop itself (unbatch, the extra model outputs, its metrics timers);
and Ray's: the runner's other threads (Ray's core worker) during the calls, the driver's wall per call beyond the
runner's own time in sample(), and the CPU of Ray's processes (GCS, raylet, ...) and of the driver's other threads
(workspace_tools.bench.rllib's split), and serialising a fragment's episodes as Ray returns them to the driver.

The learner (on the driver, num_learners=0): per Algorithm.train() the wall of learner_group.update, of sampling
(synchronous_parallel_sample) and of sync_weights, by env step of the train batch.

    ./ws exec python -m workspace_tools.bench.rllib_profile [--robot cube|hopper] [--task NAME] [--hidden-units U]
        [--fragment 256] [--fragments 4] [--updates 3] [--envs 1] [--envs-per-runner 1] [--rate 200] [--top 20]
        [--json FILE]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

PARTS = ("physics", "our_env", "vector_env", "env_to_module", "torch_forward", "module_to_env", "episode_bookkeeping",
         "rest_of_sample")
BOOKKEEPING = ("add_env_reset", "add_env_step", "cut", "validate", "to_numpy")


def _non_main_thread_cpu() -> float:
    """CPU seconds of this process's threads other than its main thread."""
    from workspace_tools.bench.common import cpu_seconds, stat_fields
    pid, total = os.getpid(), 0.0
    for tid in os.listdir(f"/proc/{pid}/task"):
        if int(tid) != pid:
            try:
                total += cpu_seconds(stat_fields(f"{pid}/task/{tid}"))
            except OSError:
                continue
    return total


class _Clock:
    """Inclusive main-thread CPU seconds per part, from wrappers around callables."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)

    def wrap(self, part: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            start = time.thread_time()
            try:
                return function(*args, **kwargs)
            finally:
                self.seconds[part] += time.thread_time() - start
        return timed


def _profile_runner(runner: Any, fragment: int, fragments: int) -> dict[str, Any]:
    """On the env runner: `fragments` calls of sample(), timed by part (module docstring)."""
    import pybullet
    from ray.rllib.env.single_agent_episode import SingleAgentEpisode

    from robot_rl.agents.rllib.runners import EpisodeTap
    clock = _Clock()
    saved = {"step": pybullet.stepSimulation, "tap": EpisodeTap.step,
             **{name: getattr(SingleAgentEpisode, name) for name in BOOKKEEPING}}
    pybullet.stepSimulation = clock.wrap("physics", saved["step"])
    EpisodeTap.step = clock.wrap("env", saved["tap"])  # type: ignore[method-assign]
    for name in BOOKKEEPING:
        setattr(SingleAgentEpisode, name, clock.wrap("bookkeeping", saved[name]))
    instance = {"_try_env_step": "vector", "_env_to_module": "env_to_module", "_module_to_env": "module_to_env",
                "_make_on_episode_callback": "bookkeeping", "_new_episode": "bookkeeping",
                "_increase_sampled_metrics": "bookkeeping"}
    own = {attribute: runner.__dict__[attribute] for attribute in instance if attribute in runner.__dict__}
    for attribute, part in instance.items():
        setattr(runner, attribute, clock.wrap(part, getattr(runner, attribute)))
    runner.module.forward_exploration = clock.wrap("forward", runner.module.forward_exploration)
    try:
        steps, sample_s, cpu0, ray0, serialise = 0, 0.0, time.thread_time(), _non_main_thread_cpu(), 0.0
        for _ in range(fragments):
            wall = time.perf_counter()
            episodes = runner.sample(num_timesteps=fragment)
            sample_s += time.perf_counter() - wall
            steps += sum(len(episode) for episode in episodes)
            start = time.thread_time()
            _serialise(episodes)
            serialise += time.thread_time() - start
        sample_cpu, ray_threads = time.thread_time() - cpu0 - serialise, _non_main_thread_cpu() - ray0
    finally:
        pybullet.stepSimulation = saved["step"]
        EpisodeTap.step = saved["tap"]  # type: ignore[method-assign]
        for name in BOOKKEEPING:
            setattr(SingleAgentEpisode, name, saved[name])
        for attribute in instance:  # the pipelines are the runner's own attributes, the methods its class's
            if attribute in own:
                setattr(runner, attribute, own[attribute])
            else:
                delattr(runner, attribute)
        del runner.module.forward_exploration
    c = clock.seconds
    parts = {"physics": c["physics"], "our_env": c["env"] - c["physics"], "vector_env": c["vector"] - c["env"],
             "env_to_module": c["env_to_module"], "torch_forward": c["forward"], "module_to_env": c["module_to_env"],
             "episode_bookkeeping": c["bookkeeping"]}
    parts["rest_of_sample"] = sample_cpu - sum(parts.values())
    return {"steps": steps, "sample_wall_s": sample_s, "sample_cpu_s": sample_cpu, "parts_s": parts,
            "ray_threads_s": ray_threads, "serialise_s": serialise}


def _serialise(episodes: list[Any]) -> None:
    """Serialise a fragment's episodes as Ray does for an actor task's result (its serialization context)."""
    import ray
    ray._private.worker.global_worker.get_serialization_context().serialize(episodes)


def _learner_timing(algorithm: Any, updates: int) -> dict[str, Any]:
    """`updates` Algorithm.train() calls on the driver, with the wall of their parts: sampling, the learner's update,
    the weights' sync."""
    from ray.rllib.algorithms.ppo import ppo as ppo_module
    from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED
    wall: dict[str, float] = defaultdict(float)

    def timed(part: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                wall[part] += time.perf_counter() - start
        return call
    sample = ppo_module.synchronous_parallel_sample
    ppo_module.synchronous_parallel_sample = timed("sample", sample)
    algorithm.learner_group.update = timed("learner_update", algorithm.learner_group.update)
    algorithm.env_runner_group.sync_weights = timed("sync_weights", algorithm.env_runner_group.sync_weights)
    steps, start, cpu = 0, time.perf_counter(), time.thread_time()
    try:
        for _ in range(updates):
            steps += int(algorithm.train()[ENV_RUNNER_RESULTS][NUM_ENV_STEPS_SAMPLED])
    finally:
        ppo_module.synchronous_parallel_sample = sample
        del algorithm.learner_group.update, algorithm.env_runner_group.sync_weights
    total = time.perf_counter() - start
    return {"steps": steps, "train_wall_s": total, "driver_main_cpu_s": time.thread_time() - cpu, **wall}


def profile(robot: str, task_name: str | None, hidden_units: int | None, fragment: int, fragments: int, updates: int,
            envs: int, envs_per_runner: int, rate: int) -> dict[str, Any]:
    """The profile (module docstring) as a dict."""
    from robot_rl import DEFAULT_HOOKS, RunDirectory, find_agent, find_task
    from workspace_tools.bench.common import ROBOTS
    from workspace_tools.robots import ROBOTS as ROBOT_REGISTRY
    agent = find_agent("rllib_ppo")
    if task_name is None:
        task = ROBOTS[robot].task
    else:
        import importlib
        task = find_task(list(importlib.import_module(ROBOT_REGISTRY[robot].package).TASKS), task_name)
    params = task.default_params()
    changes: dict[str, Any] = {"rollout_fragment_length": fragment}
    if hidden_units is not None:
        changes["hidden_units"] = hidden_units
    if envs_per_runner != 1:
        changes["envs_per_runner"] = envs_per_runner
    agent_params: Any = dataclasses.replace(agent.load_params(), **changes)  # type: ignore[type-var]
    vector = agent.make_vector_env(task, envs, "direct", 0, params, 10.0)
    import tempfile

    from workspace_tools.bench.rllib import _cpu_split, _thread_cpu, _timed_sample
    try:
        with tempfile.TemporaryDirectory(prefix="rllib-profile-") as folder:
            trainer: Any = agent.make_trainer(vector, task, params, RunDirectory(folder, agent.checkpoint_name),
                                              DEFAULT_HOOKS, agent_params=agent_params, max_steps=None)
            algorithm = trainer.algorithm
            algorithm.train()  # warm-up: the first fragment resets the envs, the first update builds the optimiser
            learner = _learner_timing(algorithm, updates)
            group = algorithm.env_runner_group
            pids = {index: pid for index, _, pid in vector.runner_info()}
            before, start = _thread_cpu(set(pids.values())), time.perf_counter()
            runner_side = group.foreach_env_runner(
                lambda runner: _profile_runner(runner, fragment * envs_per_runner, fragments)
                if runner.worker_index == 1 else None,
                local_env_runner=False)
            call_wall = time.perf_counter() - start
            split = _cpu_split(before, _thread_cpu(set(pids.values())))
            sampled = _py_spy(pids[1], rate, lambda: [group.foreach_env_runner(_timed_sample, local_env_runner=False)
                                                      for _ in range(fragments)])
    finally:
        vector.close()
    own = next(r for r in runner_side if r is not None)
    return {"robot": robot, "task": task.env_id, "network": [agent_params.hidden_units] * agent_params.hidden_layers,
            "fragment": fragment, "fragments": fragments, "envs": envs, "envs_per_runner": envs_per_runner,
            "learner": learner, "runner": own, "call_wall_s": call_wall, "cpu_split_s": split,
            "observation_shape": list(vector.single_observation_space.shape or ()), "py_spy": sampled}


EPISODE = "rllib/env/single_agent_episode.py"
RUNNER = "rllib/env/single_agent_env_runner.py"
# (part, function, a piece of its file's path) of the frames that mark a part; a stack is its innermost marked
# frame's part. Lines found in the sources (_lines): physics is the line of pybullet_sim/world.py that calls
# p.stepSimulation (py-spy sees Python frames only); module-to-env the line of _sample that calls its pipeline (whose
# __call__ is ConnectorPipelineV2's, as is the env-to-module pipeline's inside its own).
MARKS = (("physics", "", "pybullet_sim/world.py:{physics})"),
         ("module_to_env", "_sample", RUNNER + ":{module_to_env})"),
         ("our_env", "step", "robot_rl/agents/rllib/runners.py"),
         ("vector_env", "_try_env_step", "rllib/env/env_runner.py"), ("env_to_module", "_env_to_module", "connector"),
         ("env_to_module", "__call__", "env_to_module_pipeline.py"),
         ("torch_forward", "forward_exploration", "rl_module"),
         *(("episode_bookkeeping", name, EPISODE) for name in BOOKKEEPING),
         *(("episode_bookkeeping", name, RUNNER) for name in ("_make_on_episode_callback", "_new_episode",
                                                            "_increase_sampled_metrics")),
         ("rest_of_sample", "_sample", RUNNER))


def _lines() -> dict[str, int]:
    """The source lines MARKS names: physics (p.stepSimulation in pybullet_sim/world.py), module_to_env (the call of
    self._module_to_env in SingleAgentEnvRunner._sample)."""
    from ray.rllib.env import single_agent_env_runner

    import pybullet_sim.world

    def line(module: Any, text: str) -> int:
        source = open(module.__file__, encoding="utf-8").read().splitlines()
        return next(number for number, line in enumerate(source, 1) if text in line)
    return {"physics": line(pybullet_sim.world, "p.stepSimulation("),
            "module_to_env": line(single_agent_env_runner, "to_env = self._module_to_env(")}


def classify(stack: str, lines: dict[str, int]) -> str:
    """The part of a py-spy raw stack (frames outermost first, ';'-separated, each "function (file:line)"): its
    innermost marked frame's (MARKS), else "outside_sample" (the actor task's dispatch, Ray's Python threads)."""
    for frame in reversed(stack.split(";")):
        for part, function, path in MARKS:
            name = frame.split(" (", 1)[0]  # py-spy names a method Class.method
            if (not function or name == function or name.endswith("." + function)) and path.format(**lines) in frame:
                return part
    return "outside_sample"


def _py_spy(pid: int, rate: int, work: Callable[[], Any]) -> dict[str, Any]:
    """py-spy's raw stacks of process `pid` while `work()` runs: samples by part (classify), and the functions most
    often innermost; {} without py-spy."""
    binary = shutil.which("py-spy") or os.path.join(os.path.dirname(sys.executable), "py-spy")
    if not os.path.exists(binary):
        work()
        return {}
    import tempfile
    with tempfile.TemporaryDirectory(prefix="rllib-py-spy-") as folder:
        out = os.path.join(folder, "stacks.txt")
        spy = subprocess.Popen([binary, "record", "--pid", str(pid), "--format", "raw", "--rate", str(rate),
                                "--nonblocking", "--duration", "600", "-o", out], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
        try:
            time.sleep(1.0)  # py-spy attaches
            work()
        finally:
            spy.send_signal(signal.SIGINT)  # py-spy writes its stacks and ends
            try:
                spy.wait(timeout=30)
            except subprocess.TimeoutExpired:
                spy.kill()
                spy.wait()
                print("py-spy did not end within 30 s of SIGINT: killed (check its pid's stacks file)", file=sys.stderr)
        try:
            lines = open(out, encoding="utf-8").read().splitlines()
        except OSError:
            return {}
    parts: dict[str, int] = defaultdict(int)
    marked_lines = _lines()
    leaves: dict[str, int] = defaultdict(int)
    by_part: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    for line in lines:
        stack, _, count = line.rpartition(" ")
        if not count.isdigit():
            continue
        part = classify(stack, marked_lines)
        parts[part] += int(count)
        leaves[stack.split(";")[-1]] += int(count)
        by_part[part][stack.split(";")[-1].split(" (", 1)[0]] += int(count)
    return {"samples_by_part": dict(parts), "leaves": dict(leaves),
            "functions_by_part": {part: dict(functions) for part, functions in by_part.items()}}


def report(r: dict[str, Any], top: int = 20) -> str:
    """The profile as text: CPU ms per env step by part, Ray's, the learner's, and py-spy's shares and top functions."""
    own, learner = r["runner"], r["learner"]
    steps = own["steps"]
    lines = [f"{r['task']} ({r['robot']}), network {r['network']}, observation {r['observation_shape']}, "
             f"{r['envs']} env(s), {r['envs_per_runner']} per runner, fragment {r['fragment']} per env: "
             f"{steps} env steps timed on runner 1",
             f"runner 1's sample(): {1000 * own['sample_cpu_s'] / steps:.3f} CPU ms/env step (main thread), "
             f"{1000 * own['sample_wall_s'] / steps:.3f} wall ms/env step, {steps / own['sample_wall_s']:.0f} env "
             f"steps/s"]
    for part in PARTS:
        seconds = own["parts_s"][part]
        share = 100 * seconds / own["sample_cpu_s"]
        lines.append(f"  {part:<20} {1000 * seconds / steps:7.3f} ms/env step  {share:5.1f} %")
    lines.append(f"Ray, per env step: runner's other threads {1e6 * own['ray_threads_s'] / steps:.0f} us CPU; "
                 f"serialising the fragment's episodes {1e6 * own['serialise_s'] / steps:.0f} us CPU")
    learner_steps = learner["steps"]
    lines.append(f"learner (driver), {learner_steps} env steps in {learner['train_wall_s']:.2f} s of train(): "
                 f"update {1000 * learner.get('learner_update', 0.0) / learner_steps:.3f} wall ms/env step, sampling "
                 f"{1000 * learner.get('sample', 0.0) / learner_steps:.3f}, sync_weights "
                 f"{1000 * learner.get('sync_weights', 0.0) / learner_steps:.3f}; driver main thread "
                 f"{1000 * learner['driver_main_cpu_s'] / learner_steps:.3f} CPU ms/env step")
    split, beyond = r["cpu_split_s"], r["call_wall_s"] - own["sample_wall_s"]
    lines.append(f"during the timed call ({steps} env steps, {r['call_wall_s']:.2f} s wall, runner's own "
                 f"{own['sample_wall_s']:.2f} s): Ray's CPU (its processes, every non-main thread) "
                 f"{1e6 * split['ray'] / steps:.0f} us/env step, driver main {1e6 * split['driver_main'] / steps:.0f} "
                 f"us/env step; the call's wall beyond the runner's sample() {1e6 * beyond / steps:.0f} us/env step")
    spy = r.get("py_spy") or {}
    if spy:
        total = sum(spy["samples_by_part"].values())
        inside = total - spy["samples_by_part"].get("outside_sample", 0)
        lines.append(f"py-spy, {total} samples of runner 1's process over {r['fragments']} more calls "
                     f"(share of the samples inside sample()):")
        for part in (*PARTS, "outside_sample"):
            count = spy["samples_by_part"].get(part, 0)
            lines.append(f"  {part:<20} {count:6d}  {100 * count / max(1, inside):5.1f} %")
        lines.append(f"the {top} functions most often innermost (samples):")
        for leaf, count in sorted(spy["leaves"].items(), key=lambda item: -item[1])[:top]:
            lines.append(f"  {count:6d}  {leaf}")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default="cube", choices=("cube", "hopper"))
    parser.add_argument("--task", default=None, help="a task of the robot (default: the one the bench measures)")
    parser.add_argument("--hidden-units", type=int, default=None, help="units per hidden layer (default: the YAML's)")
    parser.add_argument("--fragment", type=int, default=256, help="env steps per runner per sample() call")
    parser.add_argument("--fragments", type=int, default=4, help="sample() calls timed (and as many profiled)")
    parser.add_argument("--updates", type=int, default=3, help="train() calls timed for the learner")
    parser.add_argument("--envs", type=int, default=1, help="envs (envs:=N): N / --envs-per-runner runners")
    parser.add_argument("--envs-per-runner", type=int, default=1)
    parser.add_argument("--rate", type=int, default=200, help="py-spy's samples per second")
    parser.add_argument("--top", type=int, default=20, help="functions of py-spy's list")
    parser.add_argument("--json", default=None, help="also write the figures to this file")
    args = parser.parse_args(argv)
    result = profile(args.robot, args.task, args.hidden_units, args.fragment, args.fragments, args.updates,
                     args.envs, args.envs_per_runner, args.rate)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(result, f, indent=1)
    print(report(result, args.top))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
