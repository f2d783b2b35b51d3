"""The hopper's training end to end over ROS (hopper_training's main.launch), then evaluate.py on its Q-table."""
import csv
import json
import math
import sys
import time

import pytest
import yaml

from hopper_training.envs.stay_up import STAY_UP
from workspace_tools.paths import PROGRAMS
from workspace_tools.processes import launch_args, stop, wait_for

RECORDER = PROGRAMS / "record_rewards.py"

TRAINING_TIMEOUT = 240.0  # wall s: 3 episodes of at most 100 lockstep steps, plus roslaunch start-up
EVALUATE_TIMEOUT = 120.0
NEPISODES, NSTEPS = 3, 100

def _approx(value):
    return pytest.approx(value, rel=1e-9, abs=1e-12)


def subscribed(master, node, topics):
    _, subscribers, _ = master.params.getSystemState()
    return all(node in dict(subscribers).get(topic, []) for topic in topics)


def recorded(path):
    """(rewards, episode_rewards) recorded so far; a line still being written is left out."""
    text = path.read_text() if path.exists() else ""
    lines = [line.split() for line in text[:text.rfind("\n") + 1].splitlines()]
    return ([float(v) for name, v in lines if name == "reward"],
            [float(v) for name, v in lines if name == "episode_reward"])


def test_three_episodes_over_ros_then_evaluate(ros_master, tmp_path):
    config = yaml.safe_load(STAY_UP.config_path.read_text())
    config["nsteps"] = NSTEPS
    config_file = tmp_path / "hopper_qlearn.yaml"
    config_file.write_text(yaml.safe_dump(config))
    results = tmp_path / "results"

    record_file = tmp_path / "rewards.txt"
    with open(record_file, "w") as out:
        recorder = ros_master.start([sys.executable, str(RECORDER)], stdout=out)
    topics = ["/monoped/reward", "/monoped/episode_reward"]
    wait_for(lambda: recorder.poll() is None and subscribed(ros_master, "/reward_recorder", topics), 20.0,
             "the recorder subscribing")

    started = time.monotonic()
    training = ros_master.run(["roslaunch", "hopper_training", "main.launch", *launch_args(
        nepisodes=NEPISODES, results_dir=results, config=config_file)], timeout=TRAINING_TIMEOUT)
    log = training.stdout + training.stderr
    assert training.returncode == 0, log[-4000:]
    training_time = time.monotonic() - started
    # roslaunch exits 0 even when the required training node fails (seen with exit code 1): check its log.
    assert "Training complete: 3 episodes" in log, log[-4000:]

    run = results / "stay_up" / "latest"
    assert run.is_symlink() and run.is_dir()
    with open(run / "episodes.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["episode", "steps", "return", "epsilon", "sim_time", "wall_time", "time_upright_s",
                       "upright_whole_horizon", "fell", "x_distance", "hops", "apex_height", "forward_speed",
                       "lateral_drift"]
    episodes = rows[1:]
    assert [int(row[0]) for row in episodes] == [1, 2, 3], log[-4000:]
    steps = [int(row[1]) for row in episodes]
    returns = [float(row[2]) for row in episodes]
    assert all(1 <= n <= NSTEPS for n in steps)
    # sim_time accumulates steps * running_step (0.02 s)
    assert [float(row[4]) for row in episodes] == [
        _approx(0.02 * sum(steps[:i + 1])) for i in range(NEPISODES)]
    # epsilon decays once per episode from 0.9
    assert [float(row[3]) for row in episodes] == [_approx(0.9 * 0.99 ** (i + 1)) for i in range(NEPISODES)]

    params = yaml.safe_load((run / "params.yaml").read_text())
    assert (params["nsteps"], params["nepisodes"]) == (NSTEPS, NEPISODES)
    qtable = json.loads((run / "qtable.json").read_text())
    assert qtable["episode"] == NEPISODES and qtable["qlearn"]
    assert (run / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((run / "summary.json").read_text())
    assert summary["completed"] is True
    assert (summary["episodes"], summary["env_steps"]) == (NEPISODES, sum(steps))
    # The greedy policy's video: 20 ms steps, so one frame every 2 steps (25 frames/s, real time).
    assert "frames at 25.0 frames/s" in log and (run / "video.mp4").stat().st_size > 0, log[-4000:]
    for text in ("EP: 1", "EP: 2", "EP: 3", "Overall score", "Best 100 score"):
        assert text in log, f"no '{text}' in the training log:\n{log[-4000:]}"

    # /monoped/reward carries the cumulated reward: its last value is the last episode's return, and
    # /monoped/episode_reward ends with the returns in episodes.csv (the first messages of a run can be
    # missed while the training node's publishers connect; the last ones cannot).
    wait_for(lambda: returns[-1] in recorded(record_file)[1], 20.0, "the last episode_reward reaching the recorder")
    stop(recorder)
    rewards, episode_rewards = recorded(record_file)
    assert episode_rewards == returns[-len(episode_rewards):]
    assert rewards[-1] == returns[-1]
    assert len(rewards) <= sum(steps)  # one message per env step at most

    started = time.monotonic()
    evaluation = ros_master.run(["rosrun", "hopper_training", "evaluate.py", "--qtable", str(run), "--episodes", "2",
                                "--horizon-s", "0.2"], timeout=EVALUATE_TIMEOUT)
    assert evaluation.returncode == 0, evaluation.stdout[-2000:] + evaluation.stderr[-2000:]
    evaluate_time = time.monotonic() - started
    report = json.loads(evaluation.stdout.strip().splitlines()[-1])
    assert (report["task"], report["episodes"], report["horizon_s"]) == ("Monoped-v0", 2, _approx(0.2))
    assert report["initial_tilt"] == [0.02, 0.05]  # evaluation episodes start leaning by default
    for policy in ("greedy", "random"):
        result = report[policy]
        assert set(result) == {"mean_return", "mean_time_upright_s", "upright_whole_horizon_rate", "fell_rate",
                               "mean_x_distance", "mean_hops", "mean_apex_height", "mean_forward_speed",
                               "mean_lateral_drift"}
        assert result["fell_rate"] == _approx(1.0 - result["upright_whole_horizon_rate"])
        assert all(isinstance(v, float) and math.isfinite(v) for v in result.values())
        assert 0.0 < result["mean_time_upright_s"] <= 0.2 + 1e-9
        assert result["upright_whole_horizon_rate"] in (0.0, 0.5, 1.0)
        if result["upright_whole_horizon_rate"] == 1.0:  # episodes end by a fall or at the horizon
            assert result["mean_time_upright_s"] == _approx(0.2)
        # each step earns at most alive_reward; a fall gives done_reward
        assert result["mean_return"] <= 100.0 * result["mean_time_upright_s"] / 0.02
    print(f"training {training_time:.1f} s, evaluate {evaluate_time:.1f} s")

    evaluate = ["rosrun", "hopper_training", "evaluate.py", "--qtable", str(run), "--episodes", "1", "--horizon-s",
                "0.1", "--initial-tilt"]
    upright, bad = (ros_master.run([*evaluate, *tilt], timeout=EVALUATE_TIMEOUT) for tilt in (["0", "0"],
                                                                                               ["0.05", "0.02"]))
    assert upright.returncode == 0, upright.stderr[-2000:]
    assert json.loads(upright.stdout.strip().splitlines()[-1])["initial_tilt"] == [0.0, 0.0]
    assert bad.returncode == 2 and "'initial_tilt/low' (0.05) must not be above 'initial_tilt/high'" in bad.stderr
