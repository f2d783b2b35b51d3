"""Agent bc_dagger through the training node over ROS (hopper_training's main.launch task:=end_to_end
agent:=bc_dagger on a private master), a tiny run, then evaluate.py --run on its student; the same run with
backend:=direct (in-process, no sim node) through ./ws run; a run stopped in a DAgger round over ROS, resumed."""
import json
import os
import signal
import subprocess

import pytest
import yaml

from robot_rl import AGENTS
from workspace_tools.paths import REPO
from workspace_tools.processes import launch_args, wait_for

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


def test_backend_direct_trains_in_process_with_no_sim_node(tmp_path):
    """./ws run hopper task:=end_to_end agent:=bc_dagger backend:=direct: the launch starts the training node alone
    and the run is written as over ROS (the same tiny run)."""
    for package, node in (("hopper_training", "/monoped_gym"), ("moving_cube_training", "/movingcube_gym")):
        listed = subprocess.run([str(REPO / "ws"), "exec", "roslaunch", "--nodes", package, "main.launch",
                                 "backend:=direct"], capture_output=True, text=True, timeout=120)
        assert listed.returncode == 0 and listed.stdout.split() == [node], listed.stdout + listed.stderr
    agent_config = tmp_path / "bc_dagger.yaml"
    agent_config.write_text(yaml.safe_dump({**yaml.safe_load(AGENTS["bc_dagger"].config_path.read_text()), **TINY}))
    env = {key: value for key, value in os.environ.items() if not key.startswith("ROS_")}  # a user's terminal
    env["WS_RUNS_DIR"] = str(tmp_path / "runs")
    training = subprocess.run([str(REPO / "ws"), "run", "hopper", "task:=end_to_end", "agent:=bc_dagger",
                               "backend:=direct", f"agent_config:={agent_config}", f"results_dir:={tmp_path}/results",
                               "run:=direct", "video:=false"], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=300)
    assert training.returncode == 0, training.stdout[-4000:]
    assert "Training in-process (backend direct): the env steps a World of its own, no sim node" in training.stdout
    assert "Training complete: 3 episodes" in training.stdout, training.stdout[-4000:]
    assert "with bc_dagger, 3 episodes (as agent bc_dagger's params count them; nepisodes is not used)" in \
        training.stdout, "the run's own budget, not the task's nepisodes (200)"
    assert f"train further: ./ws run hopper task:=end_to_end agent:=bc_dagger backend:=direct " \
        f"results_dir:={tmp_path}/results agent_config:=FILE (a new run" in training.stdout \
        and "nepisodes:=6" not in training.stdout, training.stdout[-2000:]
    run = tmp_path / "results" / "end_to_end-bc_dagger" / "direct"
    for name in ("params.yaml", "episodes.csv", "agent.json", "student.npz", "student.json", "summary.json",
                 "learning_curve.png"):
        assert (run / name).is_file(), name
    summary = json.loads((run / "summary.json").read_text())
    assert summary["completed"] and [r["samples"] for r in summary["rounds"]] == [40, 60]


def test_an_unknown_backend_is_refused_in_one_line(ros_master, tmp_path):
    training = ros_master.run(["roslaunch", "hopper_training", "main.launch", *launch_args(
        backend="gazebo", results_dir=tmp_path / "results", video="false")], timeout=120)
    log = training.stdout + training.stderr
    # roslaunch itself exits 0 when its required node dies (./ws run's roslaunch_checked.py passes the node's code on)
    assert "/monoped_gym: parameter 'backend' = 'gazebo' is not one of ros, direct" in log, log[-3000:]
    assert not (tmp_path / "results").exists()


def test_a_bc_dagger_run_stopped_over_ros_in_a_round_resumes_and_repeats_no_episode(ros_master, tmp_path):
    """Ctrl-C (SIGINT to the launch) once BC is done and DAgger round 0 under way; resume:=true goes on from the
    end of BC: every episode once in episodes.csv, the rounds complete."""
    agent_config = tmp_path / "bc_dagger.yaml"
    agent_config.write_text(yaml.safe_dump({**yaml.safe_load(AGENTS["bc_dagger"].config_path.read_text()), **TINY,
                                            "dagger_episodes": 40}))
    results = tmp_path / "results"
    run = results / "end_to_end-bc_dagger" / "r"
    args = launch_args(task="end_to_end", agent="bc_dagger", agent_config=agent_config, results_dir=results,
                       video="false", run="r")

    def in_round_0():
        try:
            checkpoint = json.loads((run / "agent.json").read_text())
            return checkpoint.get("stages_done") == 1 and len(run.joinpath("episodes.csv").read_text().splitlines()) > 3
        except (OSError, ValueError):
            return False
    launch = ros_master.start(["roslaunch", "hopper_training", "main.launch", *args], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
    wait_for(in_round_0, 180, f"BC done and DAgger round 0 under way ({run}/agent.json, episodes.csv)")
    os.killpg(launch.pid, signal.SIGINT)
    output = launch.communicate(timeout=60)[0]
    assert "training interrupted after episode" in output, output[-3000:]
    stopped = json.loads((run / "summary.json").read_text())
    assert not stopped["completed"] and 2 < stopped["episodes"] < 42, stopped

    resumed = ros_master.run(["roslaunch", "hopper_training", "main.launch", *args, "resume:=true"], timeout=240)
    log = resumed.stdout + resumed.stderr
    assert f"Resuming {run.resolve()} after stage 1 of 2 (episode 2)" in log, log[-3000:]
    assert "Training complete: 42 episodes" in log, log[-3000:]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["completed"] and [r["stage"] for r in summary["rounds"]] == ["bc", "dagger 0"]
    episodes = [int(line.split(",")[0]) for line in (run / "episodes.csv").read_text().splitlines()[1:]]
    assert episodes == list(range(1, 43))


def test_a_tiny_ppo_finetune_run_over_ros_resumes_and_evaluates(ros_master, tmp_path):
    """Track A's RL stage over ROS: agent ppo_finetune from the shipped student, with pushes (end_to_end_push.yaml),
    a few PPO updates; resume:=true goes on from its model.zip; evaluate.py --run plays it."""
    agent_config = tmp_path / "ppo_finetune.yaml"
    agent_config.write_text(yaml.safe_dump({**yaml.safe_load(AGENTS["ppo_finetune"].config_path.read_text()),
                                            "n_steps": 64, "batch_size": 32, "n_epochs": 2,
                                            "frozen_policy_updates": 1}))
    results = tmp_path / "results"
    args = launch_args(task="end_to_end", agent="ppo_finetune", agent_config=agent_config, results_dir=results,
                       config=REPO / "hopper_training" / "config" / "end_to_end_push.yaml", video="false",
                       run="f", nepisodes=1000)
    run = results / "end_to_end-ppo_finetune" / "f"
    for budget in (128, 256):
        training = ros_master.run(["roslaunch", "hopper_training", "main.launch", *args, f"max_steps:={budget}",
                                   f"resume:={'true' if budget == 256 else 'false'}"], timeout=240)
        log = training.stdout + training.stderr
        assert training.returncode == 0, log[-4000:]
        assert json.loads((run / "agent.json").read_text())["num_timesteps"] == budget, log[-3000:]
    assert f"Resuming {run.resolve()} after episode" in log, log[-3000:]
    assert yaml.safe_load((run / "params.yaml").read_text())["push_speed"] == 0.3
    evaluation = ros_master.run(["rosrun", "hopper_training", "evaluate.py", "--run", str(run), "--episodes", "1",
                                 "--horizon-s", "0.2", "--push", "0.3"], timeout=120)
    assert evaluation.returncode == 0, evaluation.stderr[-3000:]
    report = json.loads(evaluation.stdout.strip().splitlines()[-1])
    assert report["push"] == 0.3 and report["greedy"]["mean_time_upright_s"] > 0.0
