"""SAC over ROS (hopper_training's main.launch, agent:=sac) on the monoped's continuous joint targets: a
short run writes every results file, then resume:=true continues it to twice the episodes; and on the
residual task (task:=residual_forward), one hop a step."""
import csv
import json

import pytest
import yaml

from hopper_training.envs.residual_forward import RESIDUAL_FORWARD
from hopper_training.envs.stay_up import STAY_UP
from robot_rl import find_agent
from workspace_tools.processes import launch_args

pytestmark = pytest.mark.deep  # needs torch and Stable-Baselines3 (requirements-deep.txt)

TRAINING_TIMEOUT = 300.0  # wall s: a few episodes of at most 20 lockstep steps, plus roslaunch start-up and torch


def _files(tmp_path):
    config = yaml.safe_load(STAY_UP.config_path.read_text())
    config.update(action_mode="targets", observation="extended", nsteps=20)
    config_file = tmp_path / "stay_up_targets.yaml"
    config_file.write_text(yaml.safe_dump(config))
    agent = yaml.safe_load(find_agent("sac").config_path.read_text())
    agent.update(learning_starts=10, batch_size=16)  # a few gradient steps within the short run
    agent_file = tmp_path / "sac.yaml"
    agent_file.write_text(yaml.safe_dump(agent))
    return config_file, agent_file


def _train(ros_master, tmp_path, nepisodes, **more):
    config_file, agent_file = _files(tmp_path)
    result = ros_master.run(["roslaunch", "hopper_training", "main.launch", *launch_args(
        agent="sac", agent_config=agent_file, config=config_file, nepisodes=nepisodes, run="sac",
        results_dir=tmp_path / "results", video="false", **more)], timeout=TRAINING_TIMEOUT)
    log = result.stdout + result.stderr
    assert result.returncode == 0 and f"Training complete: {nepisodes} episodes" in log, log[-4000:]
    return tmp_path / "results" / "stay_up-sac" / "sac", log


def test_a_short_sac_run_writes_every_results_file_and_resumes(ros_master, tmp_path):
    run, _ = _train(ros_master, tmp_path, 2)
    for name in ("episodes.csv", "params.yaml", "learning_curve.png", "summary.json", "model.zip", "agent.json"):
        assert (run / name).is_file(), name
    checkpoint = json.loads((run / "agent.json").read_text())
    assert (checkpoint["agent"], checkpoint["episode"]) == ("sac", 2)
    assert yaml.safe_load((run / "params.yaml").read_text())["action_mode"] == "targets"
    first_model = (run / "model.zip").read_bytes()

    _, log = _train(ros_master, tmp_path, 4, resume="true")
    assert f"Resuming {run} after episode 2" in log, log[-4000:]
    with open(run / "episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(row["episode"]) for row in rows] == [1, 2, 3, 4]
    assert all(1 <= int(row["steps"]) <= 20 for row in rows)
    summary = json.loads((run / "summary.json").read_text())
    assert summary["completed"] and (summary["episodes"], summary["agent"]) == (4, "sac")
    assert (run / "model.zip").read_bytes() != first_model, "the resumed run saved its own weights"


def test_sac_trains_the_residual_task_over_ros_one_hop_a_step(ros_master, tmp_path):
    config = yaml.safe_load(RESIDUAL_FORWARD.config_path.read_text())
    config.update(nsteps=300)  # 0.6 s of sim time: two or three hops an episode
    config_file = tmp_path / "residual_forward.yaml"
    config_file.write_text(yaml.safe_dump(config))
    _, agent_file = _files(tmp_path)
    result = ros_master.run(["roslaunch", "hopper_training", "main.launch", *launch_args(
        task="residual_forward", agent="sac", agent_config=agent_file, config=config_file, nepisodes=3, run="sac",
        results_dir=tmp_path / "results", video="false")], timeout=TRAINING_TIMEOUT)
    log = result.stdout + result.stderr
    assert result.returncode == 0 and "Training complete: 3 episodes" in log, log[-4000:]
    run = tmp_path / "results" / "residual_forward-sac" / "sac"
    with open(run / "episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3
    for row in rows:  # a step is a hop (~0.27 s, the first from standing shorter), not a control period (2 ms)
        assert 1 <= int(row["steps"]) <= 6, row
    assert yaml.safe_load((run / "params.yaml").read_text())["target_speed"] == 0.4
