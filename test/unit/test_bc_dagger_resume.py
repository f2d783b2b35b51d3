"""Agent bc_dagger's resume: a run stopped in a DAgger round goes on from its last finished stage (the aggregate
data saved as dagger_data.npz, the RNGs in agent.json), repeats no episode, and ends as the uninterrupted run."""
import json

import numpy as np
import pytest

from hopper_training.envs.end_to_end import END_TO_END
from hopper_training.teacher.trainer import DATA_FILE
from robot_rl import RunDirectory, RunFileError, TrainingHooks

from bc_dagger_setup import AGENT, end_to_end_env  # noqa: F401 (end_to_end_env: the env fixture)

pytestmark = pytest.mark.deep  # torch

TINY = dict(bc_episodes=2, bc_epochs=1, dagger_rounds=2, dagger_episodes=2, dagger_epochs=1, horizon_s=0.1,
            batch_size=16)


def train(root, env, name, stop_at=None, resume=False, changes=TINY):
    """A tiny run `name` under root; stop_at: the stop is asked for once that many episodes are done."""
    params = END_TO_END.default_params()
    if resume:
        run = RunDirectory.named(root, AGENT.results_name(END_TO_END), name, AGENT.checkpoint_name)
    else:
        run = RunDirectory.create(root, AGENT.results_name(END_TO_END), params.to_mapping(), END_TO_END.metric_names,
                                  run_name=name, checkpoint_name=AGENT.checkpoint_name)
    lines = []
    trainer = None

    def should_stop():
        return stop_at is not None and trainer is not None and trainer.state.episode >= stop_at
    trainer = AGENT.make_trainer(env, END_TO_END, params, run, TrainingHooks(log=lines.append, should_stop=should_stop),
                                 resume=resume, agent_params=AGENT.load_params().with_changes("test", **changes))
    return run, trainer.train(), lines


def rows(run):
    return [(r.episode, r.steps, r.return_, r.epsilon) for r in run.read_episodes()]


def test_a_run_stopped_in_a_round_resumes_from_the_last_finished_stage_and_ends_as_the_uninterrupted_one(
        tmp_path, env):
    whole, whole_summary, _ = train(tmp_path, env, "whole")
    assert [r["stage"] for r in whole_summary["rounds"]] == ["bc", "dagger 0", "dagger 1"]

    run, summary, _ = train(tmp_path, env, "stopped", stop_at=3)  # BC (episodes 1-2) done, round 0 under way
    assert not summary["completed"] and summary["episodes"] == 3 and len(rows(run)) == 3
    checkpoint = json.loads((run.path / "agent.json").read_text())
    assert checkpoint["episode"] == 2 and checkpoint["stages_done"] == 1 and checkpoint["data"]["samples"] == 40
    with np.load(run.path / DATA_FILE, allow_pickle=False) as data:
        assert data["observations"].shape == (40, 63) and data["labels"].shape == (40, 3)

    run, summary, lines = train(tmp_path, env, "stopped", resume=True)
    assert any(line.startswith(f"Resuming {run.path} after stage 1 of 3 (episode 2)") for line in lines), lines
    assert summary["completed"] and summary["episodes"] == 6
    assert [r["stage"] for r in summary["rounds"]] == ["bc", "dagger 0", "dagger 1"]
    assert [r[0] for r in rows(run)] == [1, 2, 3, 4, 5, 6]  # episode 3 collected anew, not twice
    assert rows(run) == rows(whole)  # same seeds, same RNG states: the uninterrupted run's episodes
    assert (run.path / "student.npz").read_bytes() == (whole.path / "student.npz").read_bytes()
    assert [r["samples"] for r in summary["rounds"]] == [r["samples"] for r in whole_summary["rounds"]] == [40, 80, 120]


def test_a_run_stopped_before_its_refit_resumes_and_ends_as_the_uninterrupted_one(tmp_path, env):
    changes = {**TINY, "refit_epochs": 2}
    whole, whole_summary, _ = train(tmp_path, env, "whole", changes=changes)
    assert [r["stage"] for r in whole_summary["rounds"]] == ["bc", "dagger 0", "dagger 1", "refit"]
    run, summary, _ = train(tmp_path, env, "stopped", stop_at=5, changes=changes)  # in round 1
    assert not summary["completed"]
    run, summary, lines = train(tmp_path, env, "stopped", resume=True, changes=changes)
    assert any(line.startswith(f"Resuming {run.path} after stage 2 of 4 (episode 4)") for line in lines), lines
    assert summary["completed"] and [r["stage"] for r in summary["rounds"]] == ["bc", "dagger 0", "dagger 1", "refit"]
    assert rows(run) == rows(whole)
    assert (run.path / "student.npz").read_bytes() == (whole.path / "student.npz").read_bytes()


def test_a_resume_whose_data_is_not_the_checkpoints_is_refused_and_writes_nothing(tmp_path, env):
    run, _, _ = train(tmp_path, env, "stopped", stop_at=3)
    with np.load(run.path / DATA_FILE, allow_pickle=False) as data:
        np.savez(run.path / DATA_FILE, observations=data["observations"] * 2, labels=data["labels"])
    before = {path.name: path.read_bytes() for path in run.path.iterdir() if path.is_file()}
    with pytest.raises(RunFileError, match=r"dagger_data.npz: not the data the checkpoint recorded \(40 samples"):
        train(tmp_path, env, "stopped", resume=True)
    after = {path.name: path.read_bytes() for path in run.path.iterdir() if path.is_file()}
    assert after == before


def test_a_resume_with_other_agent_params_is_refused_in_one_line(tmp_path, env):
    run, _, _ = train(tmp_path, env, "stopped", stop_at=3)
    params = END_TO_END.default_params()
    with pytest.raises(ValueError, match=r"its agent params differ from this run's \(dagger_rounds 2 there, 3 here"):
        AGENT.make_trainer(env, END_TO_END, params, RunDirectory.named(tmp_path, AGENT.results_name(END_TO_END),
                                                                       "stopped", AGENT.checkpoint_name),
                           TrainingHooks(), resume=True,
                           agent_params=AGENT.load_params().with_changes("test", **{**TINY, "dagger_rounds": 3}))


def test_a_shipped_student_is_refused_a_resume_in_one_line(tmp_path, env):
    from workspace_tools.ship import ship_run
    run, _, _ = train(tmp_path, env, "whole")
    ship_run(run.path, tmp_path / AGENT.results_name(END_TO_END) / "shipped")
    with pytest.raises(ValueError, match=r"it has no data, rng, torch_generator: a shipped student .* does not resume"):
        train(tmp_path, env, "shipped", resume=True)


def test_a_resume_whose_teacher_had_other_gains_is_refused_in_one_line(tmp_path, env):
    run, _, _ = train(tmp_path, env, "stopped", stop_at=3)
    checkpoint = json.loads((run.path / "agent.json").read_text())
    assert checkpoint["teacher_gains"]["placement_kv"] == 0.1  # the teacher at 5 ms (FIVE_MS_GAIN_CHANGES)
    checkpoint["teacher_gains"]["placement_kv"] = 0.2
    (run.path / "agent.json").write_text(json.dumps(checkpoint))
    with pytest.raises(ValueError, match=r"teacher's gains differ from today's \(placement_kv 0.2 there, 0.1 here\)"):
        train(tmp_path, env, "stopped", resume=True)
