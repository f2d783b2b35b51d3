"""./ws bench's rllib section (pure: no Ray, no envs): its summary of the repetitions' samples, the report's JSON
shape, and its table rows (the cube's alone), from hand-made figures."""
import json
import statistics
from collections import defaultdict

import workspace_tools.bench.table as bench
from workspace_tools.bench.rllib import CPU_PARTS, RLLIB_ENVS, rllib_summary, sync_bound


def samples() -> dict:
    """Three repetitions' samples as rllib_rep appends them."""
    s: dict = defaultdict(list)
    for n, rllib, sb3 in ((1, [80.0, 90.0, 85.0], [70.0, 66.0, 68.0]), (2, [60.0, 150.0, 57.0], [300.0, 150.0, 147.0])):
        s[f"rllib_rllib_{n}"] += rllib
        s[f"rllib_sb3_{n}"] += sb3
        s[f"rllib_ratio_{n}"] += [r / b for r, b in zip(rllib, sb3)]
        s[f"rllib_rllib_sample_{n}"] += [200.0 * n] * 3
        s[f"rllib_sb3_sample_{n}"] += [250.0 * n] * 3
        s[f"rllib_sb3_cpu_{n}"] += [4.2] * 3
        s[f"rllib_ray_share_{n}"] += [0.03, 0.06, 0.04]
        s[f"rllib_sample_call_ray_ms_{n}"] += [2.0, 3.0, 2.5]
        for part, value in zip(CPU_PARTS, (4.94, 1.73, 0.26)):
            s[f"rllib_cpu_{part}_{n}"] += [value] * 3
        s[f"rllib_bound_ratio_{n}"] += [sync_bound(4.94, 1.73, n) / b for b in sb3]
    s["rllib_batched_2"] += [100.0, 160.0, 90.0]
    s["rllib_batched_ratio_2"] += [b / sb3 for b, sb3 in zip(s["rllib_batched_2"], s["rllib_sb3_2"])]
    s["rllib_batched_sample_2"] += [210.0, 190.0, 200.0]
    s["rllib_batched_cpu_runner_main_2"] += [3.7, 3.9, 3.8]
    s["rllib_batched_ray_share_2"] += [0.02, 0.03, 0.025]
    return s


def report() -> dict:
    s = samples()
    return {"machine": "test", "date": "2026-11-27", "load_average_at_end": 0.5, "repetitions": 3,
            "sections": ["rllib"], "cube": {"running_step": 0.06, "rllib": rllib_summary(s, statistics.median),
                                            "per_repetition": dict(s)}}


def test_the_summary_is_the_median_of_each_figure_by_n_and_is_json():
    summary = json.loads(json.dumps(report()))["cube"]["rllib"]
    assert summary["envs"] == list(RLLIB_ENVS)
    assert summary["steps_per_s"] == {"rllib": {"1": 85.0, "2": 60.0}, "sb3_pipe": {"1": 68.0, "2": 150.0}}
    assert summary["ratio_rllib_to_sb3"]["2"] == statistics.median([60 / 300, 150 / 150, 57 / 147]), \
        "the median of each repetition's ratio, not the ratio of the medians"
    assert summary["ray_cpu_share"] == {"1": 0.04, "2": 0.04}
    assert set(summary["rllib_cpu_ms_per_step"]) == {"runner_main", "driver_main", "ray"}
    assert summary["sample_steps_per_s"] == {"rllib": {"1": 200.0, "2": 400.0}, "sb3_pipe": {"1": 250.0, "2": 500.0}}
    assert summary["batched"] == {"2": {"steps_per_s": 100.0, "ratio_to_sb3": statistics.median([1 / 3, 160 / 150,
                                                                                                 90 / 147]),
                                        "runner_cpu_ms_per_step": 3.8, "ray_cpu_share": 0.025,
                                        "sample_steps_per_s": 200.0}}


def test_the_rows_are_the_cubes_with_the_ratio_and_share_ranges(capsys):
    bench.print_table(report())
    lines = capsys.readouterr().out.splitlines()

    def cells(label):
        [line] = [line for line in lines if line.startswith(f"| {label} ")]
        return [cell.strip() for cell in line.split("|")[2:4]]
    assert cells("RLlib PPO, N = 2 runners, train env steps/s") == ["60", ""]
    assert cells("SB3 PPO, N = 2 pipe workers, train env steps/s") == ["150", ""]
    assert cells("RLlib / SB3 PPO training, N = 2") == ["0.39", ""]
    assert cells("RLlib / SB3 PPO training, N = 2, at most (sync_bound: runners' CPU / N + learner's)") == \
        ["1.59", ""], "1000 / (4.94 / 2 + 1.73) env steps/s over SB3's 150 (the median repetition's)"
    assert cells("RLlib, N = 2, CPU ms/env step: runners' sample()") == ["4.94", ""]
    assert cells("RLlib, N = 2, CPU ms/env step: Ray's own") == ["0.26", ""]
    assert cells("RLlib, N = 2: Ray's CPU share") == ["0.040", ""]
    assert cells("sampling only, N = 2, RLlib runners, env steps/s") == ["400", ""]
    assert cells("sampling only, N = 2: Ray's wall per sample call, ms") == ["2.5", ""]
    ranges = [line.split("|")[2].strip() for line in lines if line.startswith("|   RLlib / SB3: lowest-highest")]
    assert ranges == ["1.14-1.36", "0.20-1.00"], "N = 1, then N = 2"
    batched = "RLlib, N = 2 envs in 1 runner (envs_per_runner 2)"
    assert cells(f"{batched}, train env steps/s") == ["100", ""]
    assert cells(f"{batched} / SB3 PPO training") == ["0.61", ""]
    assert cells(f"{batched}, CPU ms/env step: runner's sample()") == ["3.80", ""]
    assert [line.split("|")[2].strip() for line in lines if line.startswith("|   batched / SB3: lowest-high")] == \
        ["0.33-1.07"]
    assert not any(line.startswith("| vector env") for line in lines), "a section not run has no rows"


def test_the_page_has_the_sections_rows():
    page = bench.markdown(report(), "./ws bench --sections rllib")
    assert "| RLlib, N = 1: Ray's CPU share | 0.040 |  |" in page


def test_synchronous_ppo_is_bounded_by_the_runners_cpu_shared_over_them_plus_the_learners():
    assert sync_bound(4.0, 1.0, 2) == 1000.0 / 3.0, "2 runners sample in parallel (2 ms), then the learner (1 ms)"
    assert sync_bound(4.0, 1.0, 1) == 200.0
