"""Short training runs over ROS repeat recorded ones to the last bit: the cube's one_disk_walk (20 episodes) and
the monoped's stay_up (3 episodes), tabular Q-learning, seed 0, with the params.yaml each recorded run wrote as
the config (config.yaml; the cube's under its namespace).

The recordings (test/data/bit_for_bit/) were made with `./ws run cube nepisodes:=20 seed:=0 video:=false` and
`./ws run hopper nepisodes:=3 seed:=0 video:=false` on 2026-11-27, before the house redesign (issue 38) moved
the code: a move that changed behaviour changes a digit here. Every column but wall_time is compared as written."""
import csv

import pytest

from workspace_tools.paths import REPO
from workspace_tools.processes import launch_args

RECORDED = REPO / "test" / "data" / "bit_for_bit"
TRAINING_TIMEOUT = 240.0  # wall s: a few seconds of sim time each, plus start-up


def rows(path):
    with open(path, newline="") as f:
        return [{key: value for key, value in row.items() if key != "wall_time"} for row in csv.DictReader(f)]


@pytest.mark.parametrize(("package", "task", "recording", "episodes"), [
    ("moving_cube_training", "one_disk_walk", "cube", 20),
    ("hopper_training", "stay_up", "stay_up", 3),
])
def test_a_short_run_repeats_its_recording(ros_master, tmp_path, package, task, recording, episodes):
    recorded = RECORDED / recording
    results = tmp_path / "results"
    training = ros_master.run(["roslaunch", package, "main.launch", *launch_args(
        task=task, nepisodes=episodes, seed=0, results_dir=results, config=recorded / "config.yaml", video="false")],
        timeout=TRAINING_TIMEOUT)
    log = training.stdout + training.stderr
    assert training.returncode == 0 and f"Training complete: {episodes} episodes" in log, log[-4000:]
    [written] = results.glob("*/latest/episodes.csv")
    assert rows(written) == rows(recorded / "episodes.csv")
