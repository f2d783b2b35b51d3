"""The monoped's hop-level task (task:=hop_in_place, one decision per hop) trained by tabular Q-learning over ROS
(hopper_training's main.launch on a private master) for three short episodes with its greedy table checked after
episodes 2 and 3 (params' selection), then evaluate.py on its Q-table and on the table the checks kept."""
import csv
import json
import time

import pytest
import yaml

from hopper_training.envs.hop_in_place import HOP_IN_PLACE
from workspace_tools.paths import REPO
from workspace_tools.processes import launch_args

TRAINING_TIMEOUT = 240.0  # wall s: 3 episodes of at most 0.5 s of sim time at 1 ms lockstep steps, plus start-up
EVALUATE_TIMEOUT = 120.0
NEPISODES, NSTEPS, RUNNING_STEP = 3, 500, 0.001  # nsteps x running_step: each episode is at most 0.5 s of sim time


def test_three_hop_level_episodes_over_ros_then_evaluate(ros_master, tmp_path):
    config = yaml.safe_load(HOP_IN_PLACE.config_path.read_text())
    assert config["running_step"] == RUNNING_STEP
    config["nsteps"] = NSTEPS
    config["selection"] = {"every": 2, "episodes": 2, "seed": 500}
    config_file = tmp_path / "hop_level.yaml"
    config_file.write_text(yaml.safe_dump(config))
    results = tmp_path / "results"

    started = time.monotonic()
    training = ros_master.run(["roslaunch", "hopper_training", "main.launch", *launch_args(
        task="hop_in_place", nepisodes=NEPISODES, results_dir=results, config=config_file, video="false")],
        timeout=TRAINING_TIMEOUT)
    log = training.stdout + training.stderr
    assert training.returncode == 0, log[-4000:]
    training_time = time.monotonic() - started
    assert f"Training complete: {NEPISODES} episodes" in log, log[-4000:]

    run = results / "hop_in_place" / "latest"
    with open(run / "episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(row["episode"]) for row in rows] == [1, 2, 3]
    for row in rows:
        steps, duration = int(row["steps"]), float(row["time_upright_s"])
        # an episode ends by a fall or at 0.5 s of sim time; its steps are hops (~0.07-0.3 s), not 1 ms periods
        assert 0.0 < duration <= NSTEPS * RUNNING_STEP + 1e-9
        assert 1 <= steps <= 10
        if row["fell"] == "False":
            assert duration == pytest.approx(NSTEPS * RUNNING_STEP)
    # the ledger's sim time is the sum of the episodes' sim time (not steps x running_step)
    assert float(rows[-1]["sim_time"]) == pytest.approx(sum(float(row["time_upright_s"]) for row in rows))
    qtable = json.loads((run / "qtable.json").read_text())
    assert qtable["task"] == "MonopedHopInPlace-v0" and qtable["episode"] == NEPISODES
    assert qtable["state_key"]["format"] == "hopper_training.hop_level_state_key/2"
    assert {action for _, action, _ in qtable["qlearn"]["q"]} <= set(range(6)) and qtable["qlearn"]["q"]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["completed"] is True and summary["env_steps"] == sum(int(row["steps"]) for row in rows)
    with open(run / "selection.csv", newline="") as f:
        checks = list(csv.DictReader(f))
    assert [int(row["episode"]) for row in checks] == [2, 3] and log.count("table check after episode") == 2
    scores = [float(row["score"]) for row in checks]
    assert all(0.0 < score <= NSTEPS * RUNNING_STEP + 1e-9 for score in scores), checks
    kept = json.loads((run / "qtable_best.json").read_text())
    assert kept["selected"]["episode"] == summary["selection"]["best_episode"] == [2, 3][scores.index(max(scores))]

    for played in (run, run / "qtable_best.json"):
        evaluation = ros_master.run(["rosrun", "hopper_training", "evaluate.py", "--run", str(played), "--episodes",
                                    "2", "--horizon-s", "0.3"], timeout=EVALUATE_TIMEOUT)
        assert evaluation.returncode == 0, evaluation.stdout[-2000:] + evaluation.stderr[-2000:]
        report = json.loads(evaluation.stdout.strip().splitlines()[-1])
        assert (report["task"], report["episodes"], report["horizon_s"]) == \
            ("MonopedHopInPlace-v0", 2, pytest.approx(0.3))
        for policy in ("greedy", "random"):
            result = report[policy]
            assert 0.0 < result["mean_time_upright_s"] <= 0.3 + 1e-9
            assert "mean_drift" in result
    print(f"training {training_time:.1f} s")


SHIPPED_RUN = "hopper_training/policies/demo"  # training seed 0's hop_in_place run, trained on 2026-11-25


def test_the_shipped_runs_first_episodes_repeat_to_the_last_bit(ros_master, tmp_path):
    """Its params as the config, seed 0, two episodes over ROS: every column of episodes.csv but the wall time
    as the shipped run wrote it. Fails where numpy's OpenBLAS kernels are not pinned (./ws pins them to
    Haswell's: docs/guide/training.md, "The same seed, the same run") on a machine whose own kernels round otherwise."""
    shipped = REPO / SHIPPED_RUN
    results = tmp_path / "results"
    training = ros_master.run(["roslaunch", "hopper_training", "main.launch", *launch_args(
        task="hop_in_place", nepisodes=2, results_dir=results, config=shipped / "params.yaml", video="false")],
        timeout=TRAINING_TIMEOUT)
    assert training.returncode == 0, (training.stdout + training.stderr)[-4000:]

    def rows(path):
        with open(path, newline="") as f:
            return [{key: value for key, value in row.items() if key != "wall_time"} for row in csv.DictReader(f)]
    assert rows(results / "hop_in_place" / "latest" / "episodes.csv") == rows(shipped / "episodes.csv")[:2]
