"""./ws bench's table (pure: a report as orchestrate() writes it, no processes): each ratio's lowest and
highest repetition beside its median, and a note when the run's machine did not have two free cores."""
import statistics

import pytest

import workspace_tools.bench.table as bench
from workspace_tools.bench.common import lockstep_speedup_bound


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
    assert lockstep_speedup_bound([0.001] * 50) == pytest.approx(2.0)
    # half the steps take 1 ms, half 3 ms: the slower of two takes 3 ms with probability 3/4, mean 2 ms
    assert lockstep_speedup_bound([0.001, 0.003] * 50) == pytest.approx(2 * 2.0 / 2.5)
    assert lockstep_speedup_bound([0.001, 0.003] * 50, n=4) == pytest.approx(4 * 2.0 / (3 - 2 / 16))


# -- ./ws bench --markdown: docs/reference/performance.md ----------------------------------------------------
def page(independent: list[float]) -> list[str]:
    data = report(len(independent), independent)
    data.update(machine="AMD EPYC, 2 cores, Linux 6.1, Debian 12.8, Python 3.11.2, pybullet 3.2.7",
                date="2026-11-25T14:05:00+00:00")
    return bench.markdown(data, "./ws bench --reps 3 --markdown").splitlines()


def test_the_page_says_how_where_and_when_it_was_measured():
    lines = page([1.9, 1.8, 2.0])
    assert lines[0] == "# Performance"
    header = "\n".join(lines[:6])
    assert "`./ws bench --reps 3 --markdown`" in header and "2026-11-25 14:05 UTC" in header
    for fact in ("AMD EPYC", "2 cores", "Linux 6.1", "Debian 12.8", "Python 3.11.2", "pybullet 3.2.7"):
        assert fact in header


def test_the_page_has_the_printed_table_rows_that_have_figures(capsys):
    lines = page([1.9, 1.8, 2.0])
    rows = [line for line in lines if line.startswith("| ")]
    assert rows[0] == "| | cube | hopper |"
    assert "| ROS / direct | 0.70 |  |" in rows
    assert "| ROS / direct: lowest-highest repetition | 0.62-0.78 |  |" in rows
    assert not any("DQN" in row for row in rows), "rows without a figure are left out"
    printed = {line.split("|")[1].strip() for line in table(capsys, report(3, [1.9, 1.8, 2.0]))[4:]
               if line.startswith("| ")}
    assert {row.split("|")[1].strip() for row in rows[1:]} <= printed


@pytest.mark.parametrize("independent, loaded", [([1.2, 1.3], True), ([1.9], False)])
def test_the_page_notes_a_loaded_machine(independent, loaded):
    text = "\n".join(page(independent))
    assert ("the machine was loaded" in text) == loaded
    assert ("two independent direct processes ran only" in text) == loaded


def test_the_page_ends_with_what_made_lockstep_fast_and_no_history():
    lines = page([1.9])
    section = lines[lines.index("## What made lockstep fast"):]
    bullets = [line for line in section if line.startswith("- ")]
    assert 5 <= len(bullets) <= 8
    assert any("SCHED_BATCH" in line for line in section) and any("replay" in line for line in section)
    assert sum(line.startswith("|---") for line in lines) == 1, "one table: no earlier runs"


def test_the_distributed_rows_give_each_transport_their_ratio_and_the_recovery_time(capsys):
    data = report(3, [1.9, 1.9, 1.9])
    pipe, ray = {"1": 700.0, "2": 1200.0}, {"1": 560.0, "2": 1080.0}
    data["cube"]["distributed"] = {"envs": [1, 2], "steps_per_s": {"pipe": pipe, "ray": ray},
                                   "ratio_ray_to_pipe": {"1": 0.8, "2": 0.9}, "node_loss_recovery_s": 15.64,
                                   "actors_start_s": 2.21,
                                   "cpu_ms_per_step": {"pipe": {"1": 0.81, "2": 0.8}, "ray": {"1": 1.9, "2": 1.726}}}
    data["cube"]["per_repetition"].update(ray_to_pipe_1=[0.8, 0.7, 0.85], ray_to_pipe_2=[0.9, 0.88, 0.95])
    lines = table(capsys, data)
    assert cube_cell(lines, "vector env, ros, N = 2, Ray actors, env steps/s") == "1080"
    assert cube_cell(lines, "vector env, ros, N = 2, pipe workers, env steps/s") == "1200"
    assert cube_cell(lines, "vector env, ros, N = 2: Ray actors / pipe workers") == "0.90"
    ranges = [line.split("|")[2].strip() for line in lines if line.startswith("|   Ray / pipe: lowest-highest")]
    assert ranges == ["0.70-0.85", "0.88-0.95"], "N = 1, then N = 2"
    assert cube_cell(lines, "node lost: its Ray actor steps again after, s") == "15.6"
    assert cube_cell(lines, "Ray actors, N = 2: start (masters, sims), s") == "2.2"
    assert cube_cell(lines, "vector env, ros, N = 2, pipe workers, CPU ms/step") == "0.80"
    assert cube_cell(lines, "vector env, ros, N = 2, Ray actors, CPU ms/step") == "1.73"


def test_the_page_says_how_soon_a_sweep_went_on_after_a_node_lost(capsys):
    data = report(1, [1.9])
    data["sweep_node_loss_recovery_s"] = 7.94
    line = "resumed from its checkpoint 7.9 s after the kill"
    assert any(line in row for row in bench.markdown(data, "./ws bench").splitlines())
    assert any(line in row for row in table(capsys, data))


# -- --sections: only the sections run are printed ------------------------------------------------
def gazebo_only() -> dict:
    """A report of `--sections gazebo`, as orchestrate() writes it."""
    robots = {robot: {"running_step": step, "config_running_step": step, "gazebo_style_rtf1_steps_per_s": rtf1,
                      "gazebo_style_max_speed_steps_per_s": fast, "per_repetition": {"gazebo_1": [rtf1],
                                                                                     "gazebo_0": [fast]}}
              for robot, step, rtf1, fast in (("cube", 0.06, 15.9, 120.4), ("hopper", 0.03, 31.0, 150.2))}
    return {"machine": "test", "date": "2026-11-25T19:00:00+00:00", "load_average_at_end": 0.5, "repetitions": 2,
            "sections": ["gazebo"], **robots}


def test_a_run_of_one_section_prints_its_rows_only(capsys):
    rows = [line for line in table(capsys, gazebo_only()) if line.startswith("| ")]
    assert [row.split("|")[1].strip() for row in rows] == [
        "", "running_step (s)", "Gazebo-style step at RTF 1, steps/s", "Gazebo-style step at max speed, steps/s"]
    assert rows[2].split("|")[2:4] == ["      15.9 ", "      31.0 "]


def test_a_page_of_one_section_has_its_rows_and_no_other_sections_heading():
    text = bench.markdown(gazebo_only(), "./ws bench --sections gazebo --markdown")
    rows = [line for line in text.splitlines() if line.startswith("| ")]
    assert rows[1:] == ["| running_step (s) | 0.06 | 0.03 |", "| Gazebo-style step at RTF 1, steps/s | 15.9 | 31.0 |",
                        "| Gazebo-style step at max speed, steps/s | 120.4 | 150.2 |"]
    assert "## What made lockstep fast" not in text and text.endswith("\n") and not text.endswith("\n\n")


def test_a_run_without_figures_per_robot_prints_no_table(capsys):
    data = {**gazebo_only(), "sections": ["training"], "cube_100_episodes_wall_s": 41.5}
    for robot in bench.ROBOTS:
        data[robot] = {"running_step": 0.06, "config_running_step": 0.06, "per_repetition": {}}
    lines = table(capsys, data)
    assert not any(line.startswith("|") for line in lines), lines
    assert "cube: 100 training episodes over ROS in 41.5 s" in lines
    page_text = bench.markdown(data, "./ws bench --sections training --markdown")
    assert "|" not in page_text and "100 episodes of cube training over ROS took 41.5 s." in page_text


def test_the_end_to_end_rows_are_the_hoppers_alone(capsys):
    data = report(3, [1.9, 1.9, 1.9])
    data["hopper"] = {"running_step": 0.005, "end_to_end": {
        "steps": 2000, "actions": "the teacher's", "ros_steps_per_s": 402.4, "direct_steps_per_s": 1104.7,
        "ratio_ros_to_direct": 0.364, "teacher_us_per_step": 397.0},
        "bc_dagger": {"direct_samples_per_s": 96.6}, "per_repetition": {"end_to_end_ratio": [0.36, 0.33, 0.4]}}
    lines = table(capsys, data)

    def cells(label):
        [line] = [line for line in lines if line.startswith(f"| {label} ")]
        return [cell.strip() for cell in line.split("|")[2:4]]
    assert cells("end_to_end, teacher acting, ROS, env steps/s") == ["", "402"]
    assert cells("end_to_end, teacher acting, direct, env steps/s") == ["", "1105"]
    assert cells("end_to_end: ROS / direct") == ["", "0.36"]
    assert cells("  end_to_end: ROS / direct: lowest-highest repetition") == ["", "0.33-0.40"]
    assert cells("bc_dagger direct, tiny budget, samples/s") == ["", "97"]
