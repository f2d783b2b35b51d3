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
  For the hopper also its end_to_end task (MonopedEndToEnd-v0, 5 ms, END_TO_END_STEPS steps) with the teacher
  (the hopping controller) acting, as behaviour cloning collects, over ROS and direct: the env's own steps/s
  (the controller's time per step left out) and their ratio.
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
  For the hopper also agent bc_dagger on the end_to_end task, direct, on a tiny budget (BC_DAGGER_TINY): its
  samples (env steps collected and labelled) per second of wall time, fitting and the run's files included.
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
- rllib (cube only): agent rllib_ppo (RLlib's PPO, its env runners on a private local Ray) against
  Stable-Baselines3's PPO on pipe workers, direct, at equal settings (workspace_tools.bench.rllib): training env
  steps/s at N = 1 and 2 envs, their ratio, where the RLlib run's CPU goes (the runners' sample(), the driver's
  learner, Ray's own: GCS, raylet, Ray's other processes and threads) and Ray's share of it, and sampling alone.

The Gazebo-style step is the tutorials' (robot_rl.backends.GazeboStyleBackend under a normal env): unpause,
publish the command, wait running_step of sim time (on /clock, throttled to 100 Hz of wall time as
gazebo_ros publishes it), pause, read the latest sensors. It is measured with the sim at
real_time_factor 1 and at 0 (as fast as possible).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from workspace_tools.bench.common import ROBOTS, SECTIONS
from workspace_tools.bench.orchestrate import orchestrate
from workspace_tools.bench.table import markdown, print_table
from workspace_tools.paths import REPO

PERFORMANCE_PAGE = REPO / "docs" / "reference" / "performance.md"


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

