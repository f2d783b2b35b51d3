"""Agent bc_dagger (issue 39, Track A) on the direct backend: the teacher's labels are the controller's output on
the student's own states, a tiny run (2 short teacher episodes, 1 BC epoch, one DAgger round) writes every file,
and evaluate.py's loader plays its student with the controller made unusable."""
import json
from dataclasses import replace

import numpy as np
import pytest

import hopper_training
from hopper_training.controller.core import HopController, HopGains, hop_input
from hopper_training.controller.policy import FIVE_MS_GAIN_CHANGES
from hopper_training.envs.end_to_end import END_TO_END
from hopper_training.robot import CONTACT_SENSOR, IMU_SENSOR, ODOMETRY_SENSOR
from hopper_training.teacher.params import BcDaggerParams
from hopper_training.teacher.student import WEIGHTS_FILE
from hopper_training.teacher.teacher import Teacher
from robot_rl import DEEP_CHECKPOINT, ParamError, RunDirectory, RunFileError, TrainingHooks

from bc_dagger_setup import AGENT, end_to_end_env  # noqa: F401 (end_to_end_env: the env fixture)

pytestmark = pytest.mark.deep  # torch

TINY = dict(bc_episodes=2, bc_epochs=1, dagger_rounds=1, dagger_episodes=1, dagger_epochs=1, horizon_s=0.1,
            batch_size=64)


def test_the_teachers_labels_on_the_students_states_are_the_controllers_output_on_those_readings(env):
    teacher, rng = Teacher(env), np.random.default_rng(0)
    observation, _ = env.reset(seed=4)
    teacher.reset()
    labels, readings = [], []
    for _ in range(150):  # the "student" here: random targets, states the teacher would never visit itself
        labels.append(teacher.label(observation))
        readings.append(env.unwrapped.readings)
        observation, *_ = env.step(rng.uniform(-0.3, 0.3, 3).astype(np.float32))
    controller, p = HopController(replace(HopGains(), **FIVE_MS_GAIN_CHANGES)), env.unwrapped.params
    start = np.array([p.start_pose.haa, p.start_pose.hfe, p.start_pose.kfe])
    for label, r in zip(labels, readings):
        targets = controller.update(hop_input(r.joints, r.imu(IMU_SENSOR), r.odometry(ODOMETRY_SENSOR),
                                              r.contact(CONTACT_SENSOR)))
        assert np.array_equal(label, np.clip((np.array(targets) - start) / p.target_range, -1, 1).astype(np.float32))
    assert len({tuple(label) for label in labels}) > 10, "the labels follow the trajectory"


def test_the_agent_refuses_tasks_without_the_teachers_actions():
    params = AGENT.load_params()
    assert isinstance(params, BcDaggerParams) and params.beta(0) == 0.5 and params.beta(2) == 0.125
    with pytest.raises(ParamError, match="bc_dagger's teacher sets the monoped's three joint targets"):
        import gymnasium
        params.check_action_space(gymnasium.spaces.Discrete(7), "agent bc_dagger on Monoped-v0")


def tiny_run(tmp_path, env, **changes):
    params = END_TO_END.default_params()
    run = RunDirectory.create(tmp_path, AGENT.results_name(END_TO_END), params.to_mapping(), END_TO_END.metric_names,
                              run_name="tiny", checkpoint_name=AGENT.checkpoint_name)
    agent_params = AGENT.load_params().with_changes("test", **{**TINY, **changes})
    lines = []
    trainer = AGENT.make_trainer(env, END_TO_END, params, run, TrainingHooks(log=lines.append),
                                 agent_params=agent_params)
    return run, trainer.train(), lines


def test_a_tiny_run_writes_every_file_and_its_student_plays_without_the_controller(tmp_path, env, monkeypatch):
    run, summary, lines = tiny_run(tmp_path, env)
    assert run.path == tmp_path / "end_to_end-bc_dagger" / "tiny"
    for name in ("params.yaml", "episodes.csv", DEEP_CHECKPOINT, "student.npz", "student.json", "summary.json",
                 "learning_curve.png"):
        assert (run.path / name).is_file(), name
    episodes = run.read_episodes()
    assert [e.epsilon for e in episodes] == [1.0, 1.0, 0.5] and all(e.steps == 20 for e in episodes)
    assert summary["completed"] and summary["episodes"] == 3 and summary["agent"] == "bc_dagger"
    assert [r["stage"] for r in summary["rounds"]] == ["bc", "dagger 0"]
    assert [r["samples"] for r in summary["rounds"]] == [40, 60]
    architecture = json.loads((run.path / "student.json").read_text())
    assert architecture["sizes"] == [63, 256, 256, 3] and len(architecture["normaliser"]["mean"]) == 63
    with np.load(run.path / "student.npz", allow_pickle=False) as arrays:
        assert sorted(arrays) == ["W0", "W1", "W2", "b0", "b1", "b2"]
    assert any(line.startswith("dagger 0: 60 samples") for line in lines)

    def no_controller(*args, **kwargs):
        raise AssertionError("the controller ran in the student's evaluation")
    monkeypatch.setattr(HopController, "update", no_controller)
    from robot_rl.evaluation import TrainedRun, evaluate
    trained = TrainedRun(run.path, hopper_training.TASKS)
    report = evaluate(trained, episodes=1, horizon_s=0.2, backend="direct", seed=1000)
    assert report["task"] == "MonopedEndToEnd-v0" and report["greedy"]["mean_time_upright_s"] > 0.0


def test_the_refit_is_a_new_student_trained_on_the_whole_aggregate_after_the_last_round(tmp_path, env):
    plain, _, _ = tiny_run(tmp_path / "plain", env)
    run, summary, lines = tiny_run(tmp_path / "refit", env, refit_epochs=3)
    assert [r["stage"] for r in summary["rounds"]] == ["bc", "dagger 0", "refit"]
    refit = summary["rounds"][-1]
    assert (refit["episodes"], refit["collect_upright"], refit["samples"], refit["epochs"]) == (0, None, 60, 3)
    assert summary["completed"] and summary["episodes"] == 3  # it collects nothing
    def collected(r):
        return [(e.steps, e.return_, e.epsilon) for e in r.read_episodes()]
    assert collected(run) == collected(plain)  # the stages before it are the run without it
    assert (run.path / WEIGHTS_FILE).read_bytes() != (plain.path / WEIGHTS_FILE).read_bytes()
    assert any(line.startswith("refit: 60 samples") for line in lines), lines
    assert any("stage refit: a new student, 60 samples" in line for line in lines), lines  # the end block
    checkpoint = json.loads((run.path / DEEP_CHECKPOINT).read_text())
    assert checkpoint["stages_done"] == 3 and checkpoint["agent_params"]["refit_epochs"] == 3


def test_weights_that_are_not_the_checkpoints_are_refused_in_one_line(tmp_path, env):
    run, _, _ = tiny_run(tmp_path, env)
    with np.load(run.path / WEIGHTS_FILE, allow_pickle=False) as arrays:
        changed = {name: arrays[name] * 2 for name in arrays}
    np.savez(run.path / WEIGHTS_FILE, **changed)
    from robot_rl.evaluation import TrainedRun
    with pytest.raises(RunFileError, match=r"student.npz: not the student's weights \(not the weights the "
                                           r"checkpoint recorded"):
        TrainedRun(run.path, hopper_training.TASKS)


def test_a_shipped_bc_dagger_run_is_its_weights_as_trained_and_plays_as_the_run(tmp_path, env):
    from robot_rl.evaluation import TrainedRun
    from workspace_tools.ship import ship_run
    run, _, _ = tiny_run(tmp_path, env)
    shipped = tmp_path / "policies" / "end_to_end"
    names = ship_run(run.path, shipped)
    assert sorted(names) == sorted(p.name for p in shipped.iterdir()) == sorted(
        ["params.yaml", "episodes.csv", "learning_curve.png", "summary.json", DEEP_CHECKPOINT, "student.npz",
         "student.json"])
    for name in ("student.npz", "student.json"):
        assert (shipped / name).read_bytes() == (run.path / name).read_bytes(), name
    trained, kept = (json.loads((folder / DEEP_CHECKPOINT).read_text()) for folder in (run.path, shipped))
    assert kept == {key: value for key, value in trained.items() if key not in ("data", "rng", "torch_generator")}
    observation, _ = env.reset(seed=3)
    actions = [TrainedRun(path, hopper_training.TASKS).policy(env, 0)(observation) for path in (run.path, shipped)]
    assert np.array_equal(*actions)


def test_a_bc_dagger_run_whose_weights_are_not_its_checkpoints_ships_nothing(tmp_path, env):
    from workspace_tools.ship import ship_run
    run, _, _ = tiny_run(tmp_path, env)
    with np.load(run.path / WEIGHTS_FILE, allow_pickle=False) as arrays:
        changed = {name: arrays[name] * 2 for name in arrays}
    np.savez(run.path / WEIGHTS_FILE, **changed)
    with pytest.raises(ValueError, match=r"not shipped, its policy does not load: .*not the weights the checkpoint"):
        ship_run(run.path, tmp_path / "policies" / "end_to_end")
    (run.path / WEIGHTS_FILE).unlink()
    with pytest.raises(ValueError, match=r"agent.json without its student.npz"):
        ship_run(run.path, tmp_path / "policies" / "end_to_end")
    assert not (tmp_path / "policies").exists() or not list((tmp_path / "policies").iterdir())
