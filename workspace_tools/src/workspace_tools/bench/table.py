"""./ws bench's report as a table: printed, and as docs/reference/performance.md."""
from __future__ import annotations

import datetime
from typing import Any

from workspace_tools.bench.common import CEILING_WARNING, DISTRIBUTED_ENVS, ROBOTS, SCALING_ENVS, SECTIONS
from workspace_tools.bench.rllib import rllib_rows


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
    _row(rows, report, "end_to_end, teacher acting, ROS, env steps/s",
         lambda r: r["end_to_end"]["ros_steps_per_s"], "{:.0f}")
    _row(rows, report, "end_to_end, teacher acting, direct, env steps/s",
         lambda r: r["end_to_end"]["direct_steps_per_s"], "{:.0f}")
    _row(rows, report, "end_to_end: ROS / direct", lambda r: r["end_to_end"]["ratio_ros_to_direct"], "{:.2f}")
    _range_row(rows, report, "end_to_end: ROS / direct", "end_to_end_ratio")
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
    _row(rows, report, "bc_dagger direct, tiny budget, samples/s",
         lambda r: r["bc_dagger"]["direct_samples_per_s"], "{:.0f}")
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
    for label, value, fmt, range_label, range_key in rllib_rows():
        _row(rows, report, label, value, fmt)
        if range_key:
            _range_row(rows, report, range_label, range_key)
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
