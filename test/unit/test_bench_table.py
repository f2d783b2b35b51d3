"""./ws bench's table (pure: a report as orchestrate() writes it, no processes): each ratio's lowest and
highest repetition beside its median, and a note when the run's machine did not have two free cores."""
import importlib.util
import statistics
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "workspace_tools/scripts/bench.py"
_spec = importlib.util.spec_from_file_location("workspace_bench", BENCH)
assert _spec is not None and _spec.loader is not None
bench = sys.modules["workspace_bench"] = importlib.util.module_from_spec(_spec)  # its dataclasses look it up
_spec.loader.exec_module(bench)


def report(repetitions: int, independent: list[float]) -> dict:
    """A lockstep + scaling report of the cube alone, with these two-process speedups per repetition."""
    ratio = [0.70, 0.62, 0.78][:repetitions]
    efficiency = {n: [0.7, 0.6, 0.8][:repetitions] for n in (2, 4)}
    cube = {"running_step": 0.06, "ros_lockstep_steps_per_s": 450.0, "direct_steps_per_s": 640.0,
            "ratio_ros_to_direct": statistics.median(ratio), "ros_lockstep_real_time_factor": 27.0,
            "scaling": {"independent_direct_processes_speedup": {"2": statistics.median(independent)}},
            "per_repetition": {"ratio": ratio, "independent_speedup_2": independent,
                               **{f"ros_efficiency_{n}": values for n, values in efficiency.items()}}}
    return {"machine": "test", "date": "2026-11-24", "load_average_at_end": 0.5, "repetitions": repetitions,
            "cube": cube}


def table(capsys, data: dict) -> list[str]:
    bench.print_table(data)
    return capsys.readouterr().out.splitlines()


def cube_cell(lines: list[str], label: str) -> str:
    [line] = [line for line in lines if line.startswith(f"| {label} ")]
    return line.split("|")[2].strip()


def test_each_ratio_gets_its_lowest_and_highest_repetition(capsys):
    lines = table(capsys, report(3, [1.9, 1.8, 2.0]))
    assert cube_cell(lines, "ROS / direct") == "0.70"
    assert cube_cell(lines, "  ROS / direct: lowest-highest repetition") == "0.62-0.78"
    speedups = [line for line in lines if line.startswith("|   speedup: lowest-highest repetition")]
    assert speedups[0].split("|")[2].strip() == "1.20-1.60", "N = 2: 2 x the efficiencies 0.6 and 0.8"
    assert not any(line.startswith("note:") for line in lines)


def test_one_repetition_has_no_range_rows(capsys):
    assert not any("lowest-highest" in line for line in table(capsys, report(1, [1.9])))


@pytest.mark.parametrize("independent, warned", [([1.12, 1.3], True), ([1.49], True), ([1.5], False)])
def test_a_run_without_two_free_cores_says_so(capsys, independent, warned):
    lines = table(capsys, report(len(independent), independent))
    notes = [line for line in lines if line.startswith("note: cube: two independent direct processes ran only")]
    assert bool(notes) == warned, lines[-3:]


def test_the_lockstep_bound_is_two_for_equal_steps_and_lower_the_wider_they_spread():
    assert bench.lockstep_speedup_bound([0.001] * 50) == pytest.approx(2.0)
    # half the steps take 1 ms, half 3 ms: the slower of two takes 3 ms with probability 3/4, mean 2 ms
    assert bench.lockstep_speedup_bound([0.001, 0.003] * 50) == pytest.approx(2 * 2.0 / 2.5)
    assert bench.lockstep_speedup_bound([0.001, 0.003] * 50, n=4) == pytest.approx(4 * 2.0 / (3 - 2 / 16))
