"""Agent bc_dagger through the training node over ROS (hopper_training's main.launch task:=end_to_end
agent:=bc_dagger on a private master), a tiny run, then evaluate.py --run on its student."""
import json

import pytest
import yaml

from robot_rl import AGENTS
from workspace_tools.processes import launch_args

pytestmark = pytest.mark.deep  # torch

TINY = dict(bc_episodes=2, bc_epochs=1, dagger_rounds=1, dagger_episodes=1, dagger_epochs=1, horizon_s=0.1,
            batch_size=64)


def test_a_tiny_bc_dagger_run_over_ros_then_evaluate(ros_master, tmp_path):
    agent_config = tmp_path / "bc_dagger.yaml"
    agent_config.write_text(yaml.safe_dump({**yaml.safe_load(AGENTS["bc_dagger"].config_path.read_text()), **TINY}))
    results = tmp_path / "results"
    training = ros_master.run(["roslaunch", "hopper_training", "main.launch", *launch_args(
        task="end_to_end", agent="bc_dagger", agent_config=agent_config, results_dir=results, video="false")],
        timeout=240)
    log = training.stdout + training.stderr
    assert training.returncode == 0, log[-4000:]
    assert "Training complete: 3 episodes" in log, log[-4000:]
    run = results / "end_to_end-bc_dagger" / "latest"
    summary = json.loads((run / "summary.json").read_text())
    assert summary["completed"] and [r["samples"] for r in summary["rounds"]] == [40, 60]
    evaluation = ros_master.run(["rosrun", "hopper_training", "evaluate.py", "--run", str(run), "--episodes", "1",
                                 "--horizon-s", "0.1"], timeout=120)
    assert evaluation.returncode == 0, evaluation.stderr[-3000:]
    report = json.loads(evaluation.stdout.strip().splitlines()[-1])
    assert report["task"] == "MonopedEndToEnd-v0" and report["greedy"]["mean_time_upright_s"] > 0.0
