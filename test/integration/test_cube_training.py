"""The cube's Q-learning training end to end over ROS (moving_cube_training's main.launch on its own master):
a short run writes every results file, two runs repeat each other, evaluate.py reports as documented, and
two backends in one node keep the lockstep guarantee (faults and bad input: test_faults.py)."""
import json
import re
import subprocess
import time
from pathlib import Path

import imageio_ffmpeg
import pytest
import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from workspace_tools.paths import REPO, ROSTESTS
from workspace_tools.processes import Processes, RosMaster, launch_args, wait_for

CONFIG = ONE_DISK_WALK.config_path
HEADER = "episode,steps,return,epsilon,sim_time,wall_time,y_distance,success"
RESULTS_FILES = ("params.yaml", "episodes.csv", "qtable.json", "learning_curve.png", "summary.json", "video.mp4")


def write_config(path: Path, **changes) -> Path:
    document = yaml.safe_load(CONFIG.read_text())
    document["moving_cube"].update(changes)
    path.write_text(yaml.safe_dump(document))
    return path


def start_training(master: RosMaster, results: Path, config: Path, log: Path, **args) -> subprocess.Popen:
    with open(log, "w") as out:
        return master.start(["roslaunch", "moving_cube_training", "main.launch",
                             *launch_args(results_dir=results, config=config, **args)],
                            stdout=out, stderr=subprocess.STDOUT)


def wait_exit(process: subprocess.Popen, timeout: float, log: Path) -> int:
    try:
        return process.wait(timeout)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"roslaunch did not exit within {timeout} s:\n{log.read_text()[-4000:]}") from None


def complete_lines(csv_path: Path) -> list:
    """episodes.csv lines that end with a newline (a torn last line is not a row yet)."""
    return csv_path.read_text().split("\n")[:-1]


def episode_numbers(csv_path: Path) -> list:
    lines = complete_lines(csv_path)
    assert lines[0] == HEADER
    return [int(line.split(",")[0]) for line in lines[1:]]


# -- a short training run, shared by two tests ---------------------------------------------------

@pytest.fixture(scope="module")
def three_episodes(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("three_episodes")
    config = write_config(tmp / "config.yaml", nepisodes=3, nsteps=50)
    results, log = tmp / "results", tmp / "roslaunch.log"
    master = RosMaster(tmp / "ros", cwd=REPO)
    try:
        start = time.monotonic()
        code = wait_exit(start_training(master, results, config, log), 180, log)
        elapsed = time.monotonic() - start
    finally:
        master.close()
    return {"code": code, "results": results, "log": log.read_text(), "elapsed": elapsed}


def test_three_episodes_end_to_end_over_ros(three_episodes):
    output = three_episodes["log"]
    assert three_episodes["code"] == 0, output[-4000:]
    run = three_episodes["results"] / "moving_cube" / "latest"
    assert run.is_symlink()
    for name in RESULTS_FILES:
        assert (run / name).is_file(), f"{name} missing; {output[-3000:]}"
    assert episode_numbers(run / "episodes.csv") == [1, 2, 3]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["completed"] is True and summary["episodes"] == 3
    assert json.loads((run / "qtable.json").read_text())["episode"] == 3
    assert (run / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    params = yaml.safe_load((run / "params.yaml").read_text())
    assert (params["nepisodes"], params["nsteps"]) == (3, 50)
    assert re.search(r"^\[INFO\].*EP: 3 - ", output, re.M), output[-3000:]
    assert "REQUIRED process [movingcube_gym" in output and "process has finished cleanly" in output
    # The greedy policy's video: one episode of at most 10 s of sim time at 1 frame per 0.06 s step.
    video = re.search(r"Video of the greedy policy: (\S+) \((\d+) frames at 16.7 frames/s", output)
    assert video and Path(video[1]) == (run / "video.mp4").resolve(), output[-3000:]
    assert 1 <= int(video[2]) <= 1 + round(10.0 / 0.06)
    assert imageio_ffmpeg.count_frames_and_secs(str(run / "video.mp4"))[0] == int(video[2])
    assert not (run / "video.partial.mp4").exists()


def test_two_training_runs_over_ros_with_the_same_seed_write_identical_returns(three_episodes, tmp_path):
    """Lockstep makes training reproducible: a second run on a fresh master and sim repeats the first."""
    config = write_config(tmp_path / "config.yaml", nepisodes=3, nsteps=50)
    results, log = tmp_path / "results", tmp_path / "roslaunch.log"
    master = RosMaster(tmp_path / "ros", cwd=REPO)
    try:
        assert wait_exit(start_training(master, results, config, log, video="false"), 180, log) == 0, \
            log.read_text()[-3000:]
    finally:
        master.close()
    assert not (results / "moving_cube" / "latest" / "video.mp4").exists(), "video:=false writes no video"

    def returns(root: Path) -> list:
        return [line.split(",")[2] for line in complete_lines(root / "moving_cube" / "latest" / "episodes.csv")[1:]]
    first, second = returns(three_episodes["results"]), returns(results)
    assert len(first) == 3 and first == second
    assert len(set(first)) > 1, "different episodes should have different returns"


def test_evaluate_prints_one_json_line(three_episodes, tmp_path):
    run = three_episodes["results"] / "moving_cube" / "latest"
    runner = Processes(tmp_path)
    try:
        outputs = [runner.run(["rosrun", "moving_cube_training", "evaluate.py", "--qtable", str(qtable),
                               "--episodes", "2", "--backend", "direct"], timeout=120)
                   for qtable in (run, run / "qtable.json")]
        missing = runner.run(["rosrun", "moving_cube_training", "evaluate.py", "--qtable",
                              str(tmp_path / "nothing"), "--episodes", "2", "--backend", "direct"], timeout=120)
    finally:
        runner.close()
    for result in outputs:
        assert result.returncode == 0, result.stderr
    report = json.loads(outputs[0].stdout.strip().splitlines()[-1])
    assert (report["task"], report["episodes"], report["horizon_s"]) == ("MovingCubeOneDiskWalk-v0", 2, 60.0)
    assert report["initial_tilt"] is None  # the cube's task has none
    for policy in ("greedy", "random"):
        assert set(report[policy]) == {"mean_return", "mean_y_distance", "success_rate"}
        assert all(isinstance(v, float) for v in report[policy].values())
        assert 0.0 <= report[policy]["success_rate"] <= 1.0
    assert outputs[0].stdout.strip().splitlines()[-1] == outputs[1].stdout.strip().splitlines()[-1], \
        "the run folder and its qtable.json are the same Q-table; the direct backend is deterministic"
    assert missing.returncode == 2 and "cannot read the trained run" in missing.stderr


def test_evaluate_video_records_greedy_episodes_and_changes_no_number(three_episodes, tmp_path):
    run, video = three_episodes["results"] / "moving_cube" / "latest", tmp_path / "greedy.mp4"
    evaluate = ["rosrun", "moving_cube_training", "evaluate.py", "--qtable", str(run), "--episodes", "3",
                "--horizon-s", "1.2"]
    runner = Processes(tmp_path)
    try:
        plain = runner.run(evaluate, timeout=120)
        recorded = runner.run([*evaluate, "--video", str(video), "--video-size", "160x120"], timeout=120)
        bad = [runner.run([*evaluate, *args], timeout=60) for args in (
            ["--video", str(tmp_path / "greedy.avi")], ["--video", str(video), "--video-episodes", "4"],
            ["--video", str(video), "--video-size", "161x120"], ["--video", str(tmp_path / "no" / "x.mp4")])]
    finally:
        runner.close()
    assert plain.returncode == 0 and recorded.returncode == 0, plain.stderr[-2000:] + recorded.stderr[-2000:]
    without, with_video = (json.loads(r.stdout.strip().splitlines()[-1]) for r in (plain, recorded))
    info = with_video.pop("video")
    assert with_video == without, "recording must not change what is evaluated"
    assert (info["path"], info["episodes"], info["fps"]) == (str(video), 3, pytest.approx(1 / 0.06))
    assert 3 <= info["frames"] <= 3 * (1 + 20)  # a frame at each reset and after each of at most 20 steps
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(video))  # ffmpeg decodes the whole file
    assert frames == info["frames"] and seconds == pytest.approx(frames * 0.06, abs=0.07)
    for result, expected in zip(bad, ("must name an .mp4 file", "--video-episodes must be from 1 to --episodes (3)",
                                      "is not WIDTHxHEIGHT in even pixels", "does not exist")):
        assert result.returncode == 2 and expected in result.stderr, result.stderr


# -- lockstep with a second backend in one node --------------------------------------------------

def test_a_second_backend_in_one_node_applies_every_command(ros_master):
    ros_master.start(["roslaunch", "pybullet_sim", "cube_sim.launch", *launch_args(paused="true")],
                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def sim_up():
        try:
            return ros_master.params.lookupService("/pybullet_sim/step")
        except Exception:  # rosgraph.MasterError until the sim registers
            return None
    wait_for(sim_up, 60, "the sim node's step service", interval=0.05)
    result = ros_master.run(["python", str(ROSTESTS / "cube_env_node.py"),
                             "--second-backend-cycles", "1000"], timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    misses = json.loads(result.stdout.strip().splitlines()[-1])
    assert misses["first"] == 0, f"the first backend missed commands: {misses}"
    assert misses["second"] == 0, f"{misses['second']} of 1000 steps of the second backend ran with a stale command"
