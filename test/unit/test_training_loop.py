"""The Q-learning loop on the cube env with the in-process (direct) backend: results files,
epsilon schedule, progress lines, resume after a crash, determinism. No ROS master."""
import csv
import dataclasses
import json

import pytest
import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import EpisodeRecord, QLearningTrainer, RunDirectory, TrainingHooks, make_env

HEADER = ["episode", "steps", "return", "epsilon", "sim_time", "wall_time", "y_distance", "success"]


def cube_params(**overrides):
    return dataclasses.replace(ONE_DISK_WALK.default_params(), **{"nepisodes": 3, "nsteps": 20, **overrides})


def new_run(tmp_path, params, run_name=None):
    return RunDirectory.create(tmp_path, "moving_cube", params.to_mapping(), ONE_DISK_WALK.metric_names, run_name)


def make_trainer(run, params, checkpoint_every=10, resume=False, log=None, **kwargs):
    env = make_env(ONE_DISK_WALK, params=params, backend="direct", seed=params.seed)
    lines = [] if log is None else log
    trainer = QLearningTrainer(env, ONE_DISK_WALK, params, run,
                               TrainingHooks(log=lines.append, checkpoint_every=checkpoint_every, **kwargs), resume)
    return trainer, env


def train(run, params, **kwargs):
    trainer, env = make_trainer(run, params, **kwargs)
    try:
        return trainer, trainer.train()
    finally:
        env.close()


def csv_rows(run):
    with open(run.episodes_csv, newline="") as f:
        return list(csv.reader(f))


def test_three_episodes_write_every_results_file(tmp_path):
    params = cube_params()
    run = new_run(tmp_path, params)
    log = []
    _, summary = train(run, params, log=log)

    rows = csv_rows(run)
    assert rows[0] == HEADER
    assert [int(r[0]) for r in rows[1:]] == [1, 2, 3]
    assert all(1 <= int(r[1]) <= params.nsteps for r in rows[1:])
    assert all(r[7] in ("True", "False") and float(r[6]) == pytest.approx(float(r[6])) for r in rows[1:])
    assert type(params).from_mapping(yaml.safe_load(run.params_yaml.read_text()), "params.yaml") == params
    checkpoint = json.loads(run.qtable_json.read_text())
    assert (checkpoint["episode"], checkpoint["task"]) == (3, "MovingCubeOneDiskWalk-v0")
    assert checkpoint["qlearn"]["q"], "the Q-table learned something"
    assert run.learning_curve_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    on_disk = json.loads(run.summary_json.read_text())
    assert on_disk == summary
    assert on_disk["completed"] is True and on_disk["episodes"] == 3
    assert set(on_disk["metrics_last_100"]) == {"mean_y_distance", "success_rate"}
    assert on_disk["headline_metric"] == "success" and on_disk["task"] == "MovingCubeOneDiskWalk-v0"
    assert on_disk["env_steps"] == sum(int(r[1]) for r in rows[1:])
    latest = tmp_path / "moving_cube" / "latest"
    assert latest.is_symlink() and latest.resolve() == run.path.resolve()
    assert RunDirectory.latest(tmp_path, "moving_cube").path == run.path
    assert [line.split(" - ")[0] for line in log if line.startswith("EP: ")] == ["EP: 1", "EP: 2", "EP: 3"]


def expected_epsilons(epsilon, discount, n):
    out = []
    for _ in range(n):
        if epsilon > 0.05:
            epsilon *= discount
        out.append(epsilon)
    return out


@pytest.mark.parametrize("epsilon, discount", [(0.9, 0.999), (0.3, 0.5)])
def test_epsilon_decays_before_each_episode_while_above_0_05(tmp_path, epsilon, discount):
    params = cube_params(epsilon=epsilon, epsilon_discount=discount, nepisodes=6, nsteps=3)
    run = new_run(tmp_path, params)
    trainer, _ = train(run, params)
    logged = [r.epsilon for r in run.read_episodes()]
    assert logged == pytest.approx(expected_epsilons(epsilon, discount, 6), rel=1e-12)
    assert trainer.qlearn.epsilon == pytest.approx(logged[-1], rel=1e-12)
    if discount == 0.5:  # 0.15, 0.075, 0.0375, then it stays: the decay stops once at or below 0.05
        assert logged[3:] == pytest.approx([0.0375] * 3)


def test_resume_after_a_crash_between_checkpoints(tmp_path):
    params = cube_params(nepisodes=5, nsteps=20)
    run = new_run(tmp_path, params, run_name="run")
    train(run, params, checkpoint_every=5)
    checkpoint = json.loads(run.qtable_json.read_text())
    assert checkpoint["episode"] == 5
    checkpointed_csv = run.episodes_csv.read_bytes()
    # The crash: episodes 6 and 7 were logged after the checkpoint, the 8th row was torn mid-write.
    for episode in (6, 7):
        run.append_episode(EpisodeRecord(episode, 999, 123456.0, 0.01, 1e6, 1e6, {"y_distance": 9.0, "success": True}))
    with open(run.episodes_csv, "a") as f:
        f.write("8,12,3.5")

    resumed = dataclasses.replace(params, nepisodes=10)
    log = []
    trainer, env = make_trainer(RunDirectory(run.path), resumed, checkpoint_every=5, resume=True, log=log)
    try:
        # The Q-table, epsilon and Q-learning RNG come from the checkpoint, not from the params.
        assert trainer.qlearn.to_dict()["q"] == checkpoint["qlearn"]["q"]
        assert trainer.qlearn.epsilon == checkpoint["qlearn"]["epsilon"]
        assert trainer.qlearn.to_dict()["rng_state"] == checkpoint["qlearn"]["rng_state"]
        assert trainer.state.episode == 5
        summary = trainer.train()
    finally:
        env.close()

    assert any(line.startswith("Resuming") and "after episode 5" in line for line in log), log
    episode_lines = [line.split(" - ")[0] for line in log if line.startswith("EP: ")]
    assert episode_lines == [f"EP: {n}" for n in range(6, 11)], "the first resumed episode is 6"
    records = run.read_episodes()
    assert [r.episode for r in records] == list(range(1, 11))
    assert run.episodes_csv.read_bytes().startswith(checkpointed_csv), "checkpointed rows are unchanged"
    assert all(r.return_ != 123456.0 and r.steps <= 20 for r in records), "rows logged after the checkpoint are re-run"
    assert run.episodes_csv.read_text().endswith("\n")
    assert records[5].epsilon == pytest.approx(checkpoint["qlearn"]["epsilon"] * params.epsilon_discount, rel=1e-12)
    assert records[5].sim_time > records[4].sim_time, "sim time carries on from the checkpoint"
    final = json.loads(run.qtable_json.read_text())
    assert final["episode"] == 10
    old_keys = {(s, a) for s, a, _ in checkpoint["qlearn"]["q"]}
    assert old_keys <= {(s, a) for s, a, _ in final["qlearn"]["q"]}
    assert summary["completed"] is True and summary["episodes"] == 10
    assert summary["env_steps"] == sum(r.steps for r in records)


def test_an_episode_stopped_midway_takes_its_visit_counts_back_with_its_updates(tmp_path):
    """With step_size visits every step of a completed episode is one counted update, and the steps of the
    episode Ctrl-C stopped are rolled back with the table: the checkpoint counts the completed episodes' steps."""
    params = cube_params(nepisodes=4, nsteps=20, step_size="visits", epsilon=0.5)
    run = new_run(tmp_path, params, run_name="run")
    steps = []

    def on_step(reward, cumulated):
        steps.append(reward)
        if len(steps) == 30:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        train(run, params, on_step=on_step)
    checkpoint = json.loads(run.qtable_json.read_text())
    completed = run.read_episodes()
    assert 0 < sum(r.steps for r in completed) < 30
    assert sum(n for _, _, n in checkpoint["qlearn"]["visits"]) == sum(r.steps for r in completed)
    assert {(s, a) for s, a, _ in checkpoint["qlearn"]["visits"]} == {(s, a) for s, a, _ in checkpoint["qlearn"]["q"]}


def test_resume_without_a_checkpoint_fails_clearly(tmp_path):
    params = cube_params()
    run = new_run(tmp_path, params)
    with pytest.raises(FileNotFoundError, match="qtable.json"):
        make_trainer(run, params, resume=True)


def test_same_seed_same_returns(tmp_path):
    params = cube_params(nepisodes=4, nsteps=30)
    returns = []
    for name in ("a", "b"):
        run = new_run(tmp_path, params, run_name=name)
        train(run, params)
        returns.append([(r.steps, r.return_) for r in run.read_episodes()])
        q = json.loads(run.qtable_json.read_text())["qlearn"]["q"]
        returns[-1].append(q)
    assert returns[0] == returns[1]
    assert len(returns[0]) == 5
    a, b = (RunDirectory(tmp_path / "moving_cube" / n) for n in "ab")
    assert [r[:5] for r in csv_rows(a)] == [r[:5] for r in csv_rows(b)], "all but wall_time is identical"

    other = dataclasses.replace(params, seed=1)
    run = new_run(tmp_path, other, run_name="other_seed")
    train(run, other)
    assert [(r.steps, r.return_) for r in run.read_episodes()] != returns[0][:4], "the seed matters"


def test_progress_lines_give_rate_eta_and_the_headline_metric(tmp_path):
    params = cube_params(nepisodes=4, nsteps=10)
    run = new_run(tmp_path, params)
    log, episode_lines = [], []
    trainer, env = make_trainer(run, params, log=log, log_episode=episode_lines.append, progress_every_s=0.0)
    try:
        trainer.train()
    finally:
        env.close()
    progress = [line for line in log if line.startswith("progress: ")]
    assert len(progress) == 4, log
    assert progress[-1].startswith("progress: episode 4/4 (100 %), ")
    assert "env steps/s, ETA 0:00:00, success_rate over the last 4 episodes: " in progress[-1]
    assert [line.split(" - ")[0] for line in episode_lines[:4]] == ["EP: 1", "EP: 2", "EP: 3", "EP: 4"]
    assert "PICTURE" in episode_lines[4] and episode_lines[5].startswith("Overall score"), episode_lines
    assert not any(line.startswith("EP: ") or "PICTURE" in line or "score" in line for line in log), \
        "per-episode lines and the tutorial's closing lines go to log_episode (quiet:=true: the debug level)"


@pytest.mark.parametrize("damage, reason", [
    (lambda c: c.pop("qlearn"), "missing 'qlearn'"),
    (lambda c: c.update(format="robot_rl.training_checkpoint/1"), "format"),
    (lambda c: c.update(task="Monoped-v0"), "task 'Monoped-v0'"),
    (lambda c: c["state"].update(episode="ten"), "wrong types"),
    (lambda c: c.update(episode=7), "differs"),
    (lambda c: c["qlearn"].update(actions=[0, 1]), "actions"),
    (lambda c: c.update(state_key={"format": "other"}), "state key"),
], ids=["no_qlearn", "old_format", "other_task", "bad_state", "episode_mismatch", "actions", "state_key"])
def test_a_damaged_checkpoint_is_refused_before_any_file_changes(tmp_path, damage, reason):
    params = cube_params(nepisodes=5, nsteps=10)
    run = new_run(tmp_path, params, run_name="run")
    train(run, params, checkpoint_every=5)
    run.append_episode(EpisodeRecord(6, 3, 1.0, 0.5, 100.0, 100.0, {"y_distance": 0.0, "success": False}))
    checkpoint = json.loads(run.qtable_json.read_text())
    damage(checkpoint)
    run.qtable_json.write_text(json.dumps(checkpoint))
    before = {p.name: p.read_bytes() for p in run.path.iterdir()}
    with pytest.raises(ValueError, match=reason) as info:
        make_trainer(run, params, resume=True)
    assert str(info.value).startswith(f"{run.qtable_json}: not a usable checkpoint")
    assert {p.name: p.read_bytes() for p in run.path.iterdir()} == before, "nothing was written"


@pytest.mark.parametrize("changes", [{"alpha": 0.5}, {"epsilon": 0.2, "q_init": 5.0}, {"epsilon_discount": 0.5},
                                     {"step_size": "visits"}],
                         ids=["alpha", "epsilon_and_q_init", "epsilon_discount", "step_size"])
def test_a_resume_with_changed_learning_params_is_refused_naming_them_as_dqns_is(tmp_path, changes):
    """A tabular resume refuses changed learning params as DeepTrainer refuses changed agent params (before: the
    checkpoint's alpha was kept without a word); nepisodes may change (a run trained further)."""
    params = cube_params(nepisodes=5, nsteps=10)
    run = new_run(tmp_path, params, run_name="run")
    train(run, params, checkpoint_every=5)
    began = {name: getattr(params, name) for name in changes}
    assert all(began[name] != value for name, value in changes.items())
    before = {p.name: p.read_bytes() for p in run.path.iterdir()}
    with pytest.raises(ValueError, match="its learning params differ from this run's") as info:
        make_trainer(run, dataclasses.replace(params, **changes, nepisodes=8), resume=True)
    expected = ", ".join(f"{name} {began[name]!r} there, {value!r} here" for name, value in changes.items())
    assert f"({expected}): resume with the params the run began with" in str(info.value)
    assert {p.name: p.read_bytes() for p in run.path.iterdir()} == before, "nothing was written"
    trainer, env = make_trainer(run, dataclasses.replace(params, nepisodes=8), resume=True)
    env.close()
    assert trainer.state.episode == 5
