#!/usr/bin/env python3
"""./ws bench: env steps per second of both robots, over ROS in lockstep, in-process, and the
tutorials' Gazebo-style step, on the real nodes. Prints a table and writes bench_results.json.

Every figure is the median of --reps repetitions, each in fresh processes (a new master, a new sim
node, a new client); within a repetition every configuration runs once, so the ROS and direct runs
are interleaved and their ratio holds on a noisy machine. Actions are random (seeded); episode
resets are part of the measured time, as in training.

The Gazebo-style step is the tutorials': unpause, publish the command, wait running_step of sim
time (on /clock, throttled to 100 Hz of wall time as gazebo_ros publishes it), pause, read the latest
sensors. It is measured with the sim at real_time_factor 1 and at 0 (as fast as possible).
"""
from __future__ import annotations

import argparse
import datetime
import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hopper_training.monoped_env import STAY_UP
from moving_cube_training.one_disk_walk import ONE_DISK_WALK
from robot_rl.task import TaskSpec, make_env
from workspace_tools.processes import Processes, RosMaster, launch_args


@dataclass(frozen=True)
class BenchRobot:
    task: TaskSpec[Any]               # the task the robot is measured on
    steps: int                        # env steps per repetition
    gazebo_steps: dict[float, int]    # Gazebo-style steps per real-time factor


ROBOTS = {"cube": BenchRobot(ONE_DISK_WALK, 3000, {1.0: 20, 0.0: 50}),
          "hopper": BenchRobot(STAY_UP, 10000, {1.0: 100, 0.0: 200})}


# -- workers: each runs in its own process and prints one JSON line -------------------------------
def _make_env(robot: str, backend: str):
    return make_env(ROBOTS[robot].task, backend=backend)


def worker_lockstep(robot: str, backend: str, steps: int) -> dict:
    import numpy as np
    if backend == "ros":
        import rospy
        rospy.init_node("bench_client")
    env = _make_env(robot, backend)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    start = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(int(rng.integers(env.action_space.n)))
        if terminated or truncated:
            env.reset()
    elapsed = time.perf_counter() - start
    env.close()
    return {"steps_per_s": steps / elapsed, "running_step": env.unwrapped.running_step}


def worker_gazebo_style(robot: str, steps: int) -> dict:
    """The tutorials' step over ROS: unpause, command, wait running_step of sim time, pause, read."""
    import threading

    import numpy as np
    import rospy
    from rosgraph_msgs.msg import Clock

    rospy.init_node("bench_gazebo_style_client")
    env = _make_env(robot, "ros").unwrapped  # only for its publishers, subscribers and action mapping
    backend, sim = env.backend, env.backend.sim
    clock = {"now": rospy.Time(0)}
    changed = threading.Condition()

    def on_clock(msg):
        with changed:
            clock["now"] = msg.clock
            changed.notify_all()
    rospy.Subscriber("/clock", Clock, on_clock, tcp_nodelay=True)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    running_step = rospy.Duration.from_sec(env.running_step)
    start = time.perf_counter()
    for _ in range(steps):
        with changed:
            target = clock["now"] + running_step
        sim.unpause()
        env._apply_action(int(rng.integers(env.action_space.n)), env.readings)
        def reached(target: rospy.Time = target) -> bool:
            return clock["now"] >= target
        with changed:
            if not changed.wait_for(reached, 10.0):
                raise RuntimeError("/clock did not advance by running_step within 10 s")
        sim.pause()
        readings = backend.latest()
        env.readings = readings
        env._observe(readings)
    elapsed = time.perf_counter() - start
    env.close()
    return {"steps_per_s": steps / elapsed}


# -- orchestration ------------------------------------------------------------------------------
def _run_worker(processes: Processes, args: list, timeout: float) -> dict:
    result = processes.run([sys.executable, __file__, "--worker", *args], timeout=timeout)
    if result.returncode != 0:
        raise RuntimeError(f"bench worker {' '.join(args)} failed:\n{result.stderr[-3000:]}")
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


def _cube_training_wall_time(log_dir: Path, episodes: int) -> float:
    master = RosMaster(log_dir)
    results = log_dir / "results"
    try:
        result = master.run(["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training", "main.launch",
                             *launch_args(results_dir=results, nepisodes=episodes)], timeout=900)
    finally:
        master.close()
    if result.returncode != 0:
        raise RuntimeError(f"cube training failed:\n{result.stdout[-3000:]}")
    return json.loads((results / "moving_cube" / "latest" / "summary.json").read_text())["wall_time_s"]


def _machine() -> str:
    import os
    from importlib.metadata import version

    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor())
    return (f"{cpu}, {os.cpu_count()} cores, {platform.platform()}, Python {platform.python_version()}, "
            f"pybullet {version('pybullet')}")


def orchestrate(reps: int, output: Path) -> dict:
    samples: dict[str, dict[str, list[float]]] = {
        robot: {k: [] for k in ("ros", "direct", "ratio", "gazebo_1", "gazebo_0")} for robot in ROBOTS}
    cube_training = []
    running_steps = {}
    with tempfile.TemporaryDirectory(prefix="bench-") as tmp_dir:
        tmp = Path(tmp_dir)
        for rep in range(reps):
            for robot, spec in ROBOTS.items():
                steps = str(spec.steps)
                ros = _with_sim(tmp / f"{rep}-{robot}-ros", robot, 0.0, ["lockstep", robot, "ros", steps])
                direct = _run_worker(Processes(tmp / f"{rep}-{robot}-direct"), ["lockstep", robot, "direct", steps],
                                     timeout=600)
                running_steps[robot] = ros["running_step"]
                samples[robot]["ros"].append(ros["steps_per_s"])
                samples[robot]["direct"].append(direct["steps_per_s"])
                samples[robot]["ratio"].append(ros["steps_per_s"] / direct["steps_per_s"])
                for rtf, gazebo_steps in spec.gazebo_steps.items():
                    style = _with_sim(tmp / f"{rep}-{robot}-gazebo{rtf}", robot, rtf,
                                      ["gazebo", robot, str(gazebo_steps)])
                    samples[robot][f"gazebo_{int(rtf)}"].append(style["steps_per_s"])
                print(f"[bench] rep {rep + 1}/{reps} {robot}: ros {ros['steps_per_s']:.0f}/s, "
                      f"direct {direct['steps_per_s']:.0f}/s", file=sys.stderr, flush=True)
            cube_training.append(_cube_training_wall_time(tmp / f"{rep}-training", 100))
            print(f"[bench] rep {rep + 1}/{reps}: 100 cube training episodes in {cube_training[-1]:.1f} s",
                  file=sys.stderr, flush=True)
    median = statistics.median
    report = {"machine": _machine(), "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
              "repetitions": reps}
    for robot in ROBOTS:
        s = samples[robot]
        report[robot] = {
            "ros_lockstep_steps_per_s": median(s["ros"]),
            "direct_steps_per_s": median(s["direct"]),
            "ratio_ros_to_direct": median(s["ratio"]),
            "ros_lockstep_real_time_factor": median(s["ros"]) * running_steps[robot],
            "gazebo_style_rtf1_steps_per_s": median(s["gazebo_1"]),
            "gazebo_style_max_speed_steps_per_s": median(s["gazebo_0"]),
        }
    report["cube_100_episodes_wall_s"] = median(cube_training)
    output.write_text(json.dumps(report, indent=2) + "\n")
    return report


def print_table(report: dict) -> None:
    rows = [("ROS lockstep env steps/s", "ros_lockstep_steps_per_s", "{:.0f}"),
            ("in-process (direct) env steps/s", "direct_steps_per_s", "{:.0f}"),
            ("ROS / direct", "ratio_ros_to_direct", "{:.2f}"),
            ("ROS lockstep x real time", "ros_lockstep_real_time_factor", "{:.1f}"),
            ("Gazebo-style step at RTF 1, steps/s", "gazebo_style_rtf1_steps_per_s", "{:.1f}"),
            ("Gazebo-style step at max speed, steps/s", "gazebo_style_max_speed_steps_per_s", "{:.1f}")]
    print(f"\n{report['machine']}\n{report['date']}, median of {report['repetitions']} repetitions\n")
    print(f"| {'':42} | {'cube':>8} | {'hopper':>8} |")
    print(f"|{'-' * 44}|{'-' * 10}|{'-' * 10}|")
    for label, key, fmt in rows:
        print(f"| {label:42} | {fmt.format(report['cube'][key]):>8} | {fmt.format(report['hopper'][key]):>8} |")
    for robot in ROBOTS:
        r = report[robot]
        ratio = r['ros_lockstep_steps_per_s'] / r['gazebo_style_rtf1_steps_per_s']
        print(f"{robot}: lockstep over ROS is {ratio:.0f}x the Gazebo-style step at RTF 1")
    print(f"cube: 100 training episodes over ROS in {report['cube_100_episodes_wall_s']:.1f} s")


def main(argv) -> int:
    if argv and argv[0] == "--worker":
        kind, robot, *rest = argv[1:]
        result = (worker_lockstep(robot, rest[0], int(rest[1])) if kind == "lockstep"
                  else worker_gazebo_style(robot, int(rest[0])))
        print(json.dumps(result))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=5, help="repetitions (fresh processes each); figures are medians")
    parser.add_argument("--output", type=Path, default=Path("bench_results.json"))
    args = parser.parse_args(argv)
    print_table(orchestrate(args.reps, args.output))
    print(f"\nwritten: {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
