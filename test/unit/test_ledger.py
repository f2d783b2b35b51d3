"""RunLedger (robot_rl.ledger), the bookkeeping every trainer hands its episodes to: the episodes.csv
row, the "EP:" line, the checkpoint cadence, the progress line, summary.json and the stop path.
With a stand-in learner: no env, no ROS master."""
import json
import math
import re

import pytest

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import Episode, RunDirectory, RunLedger, TrainingHooks, TrainingState, aggregate, restored_state


class Learner:
    def __init__(self, run):
        self.run, self.saved = run, []

    def save_checkpoint(self):
        self.saved.append(self.state.episode)
        self.run.checkpoint({"format": "test", "task": ONE_DISK_WALK.env_id, "episode": self.state.episode,
                             "state": vars(self.state)})

    def episode_label(self, epsilon):
        return f"test: epsilon {epsilon:.2f}"

    def exploration_label(self):
        return ", epsilon 0.500"

    def summary_fields(self):
        return {"learner": "test"}

    def closing_lines(self, summary, last):
        return [f"closing after {summary['episodes']} episodes, {len(last)} averaged"]


def make_ledger(tmp_path, n_envs=1, nepisodes=4, max_steps=None, **hooks):
    run = RunDirectory.create(tmp_path, "moving_cube", {}, ONE_DISK_WALK.metric_names, "run")
    learner, log = Learner(run), []
    learner.state = TrainingState()
    ledger = RunLedger(run, ONE_DISK_WALK, nepisodes, learner.state, learner,
                       TrainingHooks(log=log.append, checkpoint_every=2, **hooks), n_envs=n_envs, max_steps=max_steps)
    ledger.start()
    return ledger, learner, log


def episode(steps=5, return_=12.34, terminated=True):
    return Episode(steps=steps, return_=return_, terminated=terminated, duration=steps * 0.1,
                   info={"y_distance": 0.5, "success": terminated})


def test_an_episode_is_counted_written_and_logged(tmp_path):
    returns = []
    ledger, _, log = make_ledger(tmp_path, on_episode=returns.append)
    ledger.episode_done(episode(), highest=20.0, epsilon=0.25)
    state = ledger.state
    assert (state.episode, state.env_steps, state.highest_reward, state.last_time_steps) == (1, 5, 20.0, [5])
    assert state.sim_time == pytest.approx(0.5)
    [record] = ledger.run.read_episodes()
    assert (record.episode, record.steps, record.return_, record.epsilon) == (1, 5, 12.34, 0.25)
    assert set(record.metrics) == set(ONE_DISK_WALK.metric_names)
    assert returns == [12.34]
    assert log == ["EP: 1 - [test: epsilon 0.25] - Reward: 12.3     Time: 0:00:00"]


def test_the_ep_line_names_the_env_when_there_are_several(tmp_path):
    ledger, _, log = make_ledger(tmp_path, n_envs=2)
    for env_index in (0, 1, 0):
        ledger.episode_done(episode(terminated=False), highest=1.0, epsilon=0.5, env_index=env_index)
    # Time is the wall time since the start: on a loaded machine it may pass a second.
    assert re.fullmatch(r"EP: 3 - \[test: epsilon 0\.50\] - Reward: 12\.3     Time: \d+:\d\d:\d\d - env 1/2 "
                        r"\(episodes per env: 2, 1\)", log[-1]), log[-1]
    assert ledger.state.last_time_steps == [], "truncated episodes are no terminations"


def test_a_checkpoint_every_checkpoint_every_episodes_and_at_the_end(tmp_path):
    ledger, learner, log = make_ledger(tmp_path, nepisodes=5)
    due = []
    for _ in range(5):
        due.append(ledger.checkpoint_due())
        ledger.episode_done(episode(), highest=1.0, epsilon=0.5)
    assert due == [False, True, False, True, False] and learner.saved == [2, 4]
    assert ledger.run.learning_curve_png.is_file()
    summary = ledger.close(done=True)
    assert learner.saved == [2, 4, 5]
    assert json.loads(ledger.run.summary_json.read_text()) == summary
    assert summary["completed"] is True and summary["stopped"] is None and summary["learner"] == "test"
    assert (summary["episodes"], summary["nepisodes"], summary["env_steps"]) == (5, 5, 25)
    metrics = ONE_DISK_WALK.metrics(episode())
    assert summary["metrics_last_100"] == aggregate({name: [value] * 5 for name, value in metrics.items()})
    assert log[-1] == "closing after 5 episodes, 5 averaged"


@pytest.mark.parametrize(("done", "stopped", "expected"), [(False, None, "interrupted"), (True, "interrupted",
                                                                                          "interrupted")])
def test_a_run_that_ends_early_is_marked_incomplete(tmp_path, done, stopped, expected):
    ledger, _, _ = make_ledger(tmp_path)
    summary = ledger.close(done=done, stopped=stopped)
    assert summary["completed"] is False and summary["stopped"] == expected


def test_the_progress_line(tmp_path):
    ledger, _, log = make_ledger(tmp_path, progress_every_s=0.0)
    ledger.episode_done(episode(), highest=1.0, epsilon=0.5)
    ledger.log_progress_if_due()
    assert log[-1].startswith("progress: episode 1/4 (25 %), ")
    success = float(ONE_DISK_WALK.metrics(episode())["success"])
    assert log[-1].endswith(f" env steps/s, ETA 0:00:00, success_rate over the last 1 episodes: {success:.3g}, "
                            f"epsilon 0.500")


def test_under_a_step_budget_the_progress_line_counts_steps(tmp_path):
    """max_steps:=N: the episodes are not what ends the run, the steps are."""
    ledger, _, log = make_ledger(tmp_path, nepisodes=500, max_steps=20, progress_every_s=0.0)
    ledger.log_progress_if_due()
    assert log[-1].startswith("progress: step 0/20 (0 %), ") and "ETA ?," in log[-1], log[-1]
    ledger.episode_done(episode(steps=5), highest=1.0, epsilon=0.5)
    ledger.log_progress_if_due()
    assert log[-1].startswith("progress: step 5/20 (25 %), "), log[-1]


@pytest.mark.parametrize(("error", "reason"), [(KeyboardInterrupt(), "interrupted"),
                                               (RuntimeError("sim gone"), "error: sim gone")])
def test_the_stop_path_rolls_back_saves_and_reraises(tmp_path, error, reason):
    ledger, learner, _ = make_ledger(tmp_path)
    ledger.episode_done(episode(), highest=1.0, epsilon=0.5)
    rolled_back = []
    with pytest.raises(type(error)), ledger.saved_on_stop(rollback=lambda: rolled_back.append(True)):
        raise error
    assert rolled_back == [True] and learner.saved == [1]
    summary = json.loads(ledger.run.summary_json.read_text())
    assert (summary["completed"], summary["stopped"], summary["episodes"]) == (False, reason, 1)


def test_a_stop_request_makes_any_error_an_interruption(tmp_path):
    ledger, _, _ = make_ledger(tmp_path, should_stop=lambda: True)
    with pytest.raises(OSError), ledger.saved_on_stop():
        raise OSError("the master is gone")
    assert json.loads(ledger.run.summary_json.read_text())["stopped"] == "interrupted"


def test_the_stop_path_logs_a_failure_to_save_writes_what_it_can_and_raises_the_original_error(tmp_path):
    """A full disk: the checkpoint cannot be written, the small summary.json still says how the run ended."""
    ledger, learner, log = make_ledger(tmp_path)

    def cannot_write():
        raise OSError("disk full")
    learner.save_checkpoint = cannot_write
    with pytest.raises(RuntimeError, match="sim gone"), ledger.saved_on_stop():
        raise RuntimeError("sim gone")
    assert "could not save the run's checkpoint after episode 0: disk full" in log
    summary = json.loads(ledger.run.summary_json.read_text())
    assert (summary["completed"], summary["stopped"]) == (False, "error: sim gone")


def test_a_restored_state_is_checked_against_the_format_and_the_task():
    state = TrainingState(episode=3, highest_reward=1.5, last_time_steps=[4], sim_time=1.0, wall_time=2.0, env_steps=9)
    checkpoint = {"format": "f/1", "task": ONE_DISK_WALK.env_id, "episode": 3, "state": vars(state)}
    assert restored_state(checkpoint, "f/1", ONE_DISK_WALK) == state
    for change, reason in (({"format": "f/0"}, "format"), ({"task": "Monoped-v0"}, "task 'Monoped-v0'"),
                           ({"episode": 4}, "differs")):
        with pytest.raises(ValueError, match=reason):
            restored_state({**checkpoint, **change}, "f/1", ONE_DISK_WALK)
    with pytest.raises(ValueError, match="wrong types"):
        restored_state({**checkpoint, "state": {**vars(state), "sim_time": math.nan}}, "f/1", ONE_DISK_WALK)


@pytest.fixture
def full_disk(tmp_path):
    """A tmpfs of 256 KiB (this test runs as root; skipped where it cannot mount), unmounted after the test."""
    import os
    import subprocess
    mount = tmp_path / "disk"
    mount.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mount)],
                                           capture_output=True).returncode != 0:
        pytest.skip("needs root to mount a tmpfs")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=True)


def fill(folder):
    """Write into `folder` until the disk has no byte left."""
    with open(folder / "filler", "wb", buffering=0) as f:
        for size in (4096, 1):
            try:
                while True:
                    f.write(b"\0" * size)
            except OSError as error:
                assert error.errno == 28, error  # ENOSPC


def test_a_disk_with_no_room_left_gets_no_summary_the_stop_says_so_and_the_last_checkpoint_loads(full_disk):
    """The honest behaviour on a real full filesystem: the stop path writes what fits, and on a disk with no byte
    left nothing does; it logs each file it could not write and raises the original error. Nothing is half-written:
    the checkpoint before is whole and resumes."""
    ledger, learner, log = make_ledger(full_disk)
    for _ in range(2):
        ledger.episode_done(episode(), highest=1.0, epsilon=0.5)  # a checkpoint after episode 2
    ledger.episode_done(episode(), highest=1.0, epsilon=0.5)
    fill(full_disk)
    with pytest.raises(RuntimeError, match="sim gone"), ledger.saved_on_stop():
        raise RuntimeError("sim gone")
    assert any(line.startswith("could not save the run's checkpoint after episode 3: ") and "No space left" in line
               for line in log), log
    assert any(line.startswith("could not save the run's summary after episode 3: ") and "No space left" in line
               for line in log), log
    assert not ledger.run.summary_json.exists()
    assert ledger.run.load_checkpoint()["episode"] == 2
    assert not [p.name for p in ledger.run.path.iterdir() if p.name.startswith(".") and p.name != ".lock"], \
        "no temp file left"
