"""Unit tests for robot_rl.results (no ROS needed)."""
import json
import os

import pytest
import yaml
from PIL import Image

from robot_rl import EpisodeRecord, QLearn, RunDirectory, aggregate, moving_average

HEADER = "episode,steps,return,epsilon,sim_time,wall_time\n"
PARAMS = {"alpha": 0.1, "gamma": 0.8, "init_cube_pose": {"y": 0.0}}


def record(n):
    return EpisodeRecord(n, 10 * n, n / 3.0 - 2.0, 0.9 ** n, 1.5 * n, 0.1 * n)


def keep(state):
    """A restore callback that accepts any checkpoint."""
    return state


def test_create(tmp_path):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS, run_name="r1")
    assert run.path == tmp_path / "hopper" / "r1"
    assert (run.robot, run.name) == ("hopper", "r1")
    assert yaml.safe_load((run.path / "params.yaml").read_text()) == PARAMS
    assert (run.path / "episodes.csv").read_text() == HEADER
    link = tmp_path / "hopper" / "latest"
    assert link.is_symlink() and os.readlink(link) == "r1"
    assert RunDirectory.latest(tmp_path, "hopper").path == run.path
    with pytest.raises(FileExistsError):
        RunDirectory.create(tmp_path, "hopper", PARAMS, run_name="r1")


def test_default_names_unique_and_latest_is_newest(tmp_path):
    first = RunDirectory.create(tmp_path, "cartpole", PARAMS)
    second = RunDirectory.create(tmp_path, "cartpole", PARAMS)
    assert first.name != second.name
    assert RunDirectory.latest(tmp_path, "cartpole").name == second.name
    assert not list((tmp_path / "cartpole").glob(".*"))  # no temp files left


def test_latest_missing(tmp_path):
    with pytest.raises(FileNotFoundError, match="no previous run under .*: start without resume"):
        RunDirectory.latest(tmp_path, "hopper")


def test_append_and_read_episodes(tmp_path):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS)
    records = [record(n) for n in range(1, 4)]
    for r in records:
        run.append_episode(r)
    assert run.read_episodes() == records
    assert run.episodes_csv.read_text().splitlines()[0] + "\n" == HEADER


def test_torn_last_line_ignored(tmp_path):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS)
    run.append_episode(record(1))
    with open(run.episodes_csv, "a") as f:
        f.write("2,20,0.5")
    assert run.read_episodes() == [record(1)]


def test_checkpoint_round_trip(tmp_path):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS)
    with pytest.raises(FileNotFoundError, match="checkpoint"):
        run.load_checkpoint()
    ql = QLearn([0, 1], 0.5, 0.1, 0.9, seed=3)
    ql.learn("1_2", 0, 1.0, "2_2")
    run.checkpoint({"episode": 4, "qlearn": ql.to_dict()})
    state = run.load_checkpoint()
    assert state["episode"] == 4 and "written_at" in state
    assert QLearn.from_dict(state["qlearn"]).q == ql.q
    json.loads((run.path / "qtable.json").read_text())


def test_prepare_resume_drops_rows_after_checkpoint(tmp_path):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS)
    for n in range(1, 4):
        run.append_episode(record(n))
    run.checkpoint({"episode": 3})
    run.append_episode(record(4))  # logged, then crash before the next checkpoint
    resumed = RunDirectory.latest(tmp_path, "hopper")
    assert resumed.prepare_resume(keep)["episode"] == 3
    assert resumed.read_episodes() == [record(n) for n in range(1, 4)]
    resumed.append_episode(record(4))  # re-run: no duplicate
    assert [r.episode for r in resumed.read_episodes()] == [1, 2, 3, 4]


@pytest.mark.parametrize("n", [0, 1, 30])
def test_learning_curve_png(tmp_path, n):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS)
    for i in range(1, n + 1):
        run.append_episode(record(i))
    run.write_learning_curve()
    assert (run.path / "learning_curve.png").read_bytes().startswith(b"\x89PNG")


def test_summary(tmp_path):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS)
    run.write_summary({"episodes": 3, "best_return": 1.5})
    assert json.loads((run.path / "summary.json").read_text()) == {"episodes": 3, "best_return": 1.5}
    with pytest.raises(ValueError):
        run.write_summary({"best_return": float("nan")})


def test_metric_columns_keep_yes_no_values(tmp_path):
    run = RunDirectory.create(tmp_path, "moving_cube", PARAMS, metric_names=("y_distance", "success"))
    assert run.episodes_csv.read_text() == HEADER.rstrip("\n") + ",y_distance,success\n"
    records = [EpisodeRecord(n, n, 0.0, 0.5, n, n, {"y_distance": 0.25 * n, "success": n > 2}) for n in (1, 2, 3, 4)]
    for r in records:
        run.append_episode(r)
    assert run.metric_names == ("y_distance", "success")
    assert run.read_episodes() == records
    assert aggregate({"y_distance": [r.metrics["y_distance"] for r in records],
                      "success": [r.metrics["success"] for r in records]}) == \
        {"mean_y_distance": pytest.approx(0.625), "success_rate": 0.5}
    run.write_learning_curve("success")
    assert run.learning_curve_png.read_bytes().startswith(b"\x89PNG")
    heights = []
    for metrics in ((), ("success",), ("success", "y_distance")):
        run.write_learning_curve(*metrics)
        heights.append(Image.open(run.learning_curve_png).height)
    assert heights == [620, 820, 1020]  # a panel (200 pixels) per metric below return, above epsilon


def test_a_row_with_a_missing_column_is_reported(tmp_path):
    run = RunDirectory.create(tmp_path, "moving_cube", PARAMS, metric_names=("success",))
    with open(run.episodes_csv, "a") as f:
        f.write("1,2,3.0,0.5,1.0,1.0\n")
    with pytest.raises(ValueError, match="episodes.csv:2: bad row"):
        run.read_episodes()


@pytest.mark.parametrize("content, reason", [
    (b"\xff\xfe\x00garbage", "not UTF-8"), (b"[1, 2]", "a JSON list"), (b"{", "invalid JSON")])
def test_an_unreadable_checkpoint_names_the_file(tmp_path, content, reason):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS)
    run.qtable_json.write_bytes(content)
    with pytest.raises(ValueError, match=reason) as info:
        run.load_checkpoint()
    assert str(info.value).startswith(str(run.qtable_json))


def test_prepare_resume_refuses_a_checkpoint_ahead_of_the_episodes(tmp_path):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS)
    run.append_episode(record(1))
    run.checkpoint({"episode": 3})
    with pytest.raises(ValueError, match="fewer than the 3"):
        run.prepare_resume(keep)
    assert run.read_episodes() == [record(1)]


def test_moving_average_starts_with_the_mean_so_far():
    assert moving_average([1.0, 3.0, 5.0, 7.0], window=2).tolist() == [1.0, 2.0, 4.0, 6.0]


def test_a_run_another_process_trains_is_refused_and_the_lock_dies_with_it(tmp_path):
    """The lock is the other process's for as long as it lives; kill -9 leaves no stale lock."""
    import subprocess
    import sys

    from robot_rl import RunLockedError
    holder = subprocess.Popen([sys.executable, "-c", "import sys; from robot_rl import RunDirectory; "
                               f"RunDirectory.create({str(tmp_path)!r}, 'hopper', {{}}, run_name='r1')"
                               ".checkpoint({'episode': 0}); print('locked', flush=True); sys.stdin.read()"],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    run = RunDirectory(tmp_path / "hopper" / "r1")
    try:
        assert holder.stdout.readline() == "locked\n"
        episodes_before = run.episodes_csv.read_bytes()
        with pytest.raises(RunLockedError, match="another process is training this run") as refused:
            RunDirectory(run.path).prepare_resume(keep)
        assert str(run.path) in str(refused.value) and "\n" not in str(refused.value)
        assert run.episodes_csv.read_bytes() == episodes_before
    finally:
        holder.kill()
        holder.wait()
    assert RunDirectory(run.path).prepare_resume(keep)["episode"] == 0  # the dead holder's lock is gone


def test_a_run_by_name(tmp_path):
    run = RunDirectory.create(tmp_path, "hopper", PARAMS, run_name="first")
    RunDirectory.create(tmp_path, "hopper", PARAMS)  # latest moves on
    assert RunDirectory.named(tmp_path, "hopper", "first").path == run.path
    with pytest.raises(FileNotFoundError, match=r"no run 'second' under .*hopper \(runs: 2\d+-\d+, first\)"):
        RunDirectory.named(tmp_path, "hopper", "second")
    with pytest.raises(ValueError, match="invalid run name"):
        RunDirectory.named(tmp_path, "hopper", "../first")


@pytest.mark.parametrize("kind", ["folder", "file"])
def test_a_latest_that_is_not_a_link_is_refused_before_the_run_folder_is_made(tmp_path, kind):
    latest = tmp_path / "hopper" / "latest"
    latest.parent.mkdir()
    latest.mkdir() if kind == "folder" else latest.write_text("mine")
    with pytest.raises(ValueError, match=f"{latest} is a {kind}, not the link to the newest run kept there"):
        RunDirectory.create(tmp_path, "hopper", PARAMS, run_name="first")
    assert sorted(p.name for p in latest.parent.iterdir()) == ["latest"], "no run folder, no temp file"
