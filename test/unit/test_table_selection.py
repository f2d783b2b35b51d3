"""The greedy table checked during tabular training (params' selection, robot_rl.agents.qlearn.selection): the
checks' rows and scores, the best table kept and played again, the learner left alone, resume. The cube env on
the direct backend; no ROS master."""
import dataclasses
import json
import math

import gymnasium
import pytest

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import QLearningTrainer, RunDirectory, TrainingHooks, VectorQLearningTrainer, make_env, make_vector_env
from robot_rl.agents.qlearn.qlearn import QLearn
from robot_rl.agents.qlearn.selection import (
    BEST_CHECKPOINT,
    SelectionLog,
    SelectionState,
    check_due,
    play_greedy,
    score,
)
from robot_rl.evaluation import TrainedRun
from robot_rl.params import TableSelection


def cube_params(every=2, episodes=3, nepisodes=5, **overrides):
    params = ONE_DISK_WALK.default_params()
    return dataclasses.replace(params, nepisodes=nepisodes, nsteps=20,
                               selection=TableSelection(every=every, episodes=episodes, seed=77), **overrides)


def train(tmp_path, params, resume=False, run=None):
    if run is None:
        run = RunDirectory.create(tmp_path, "moving_cube", params.to_mapping(), ONE_DISK_WALK.metric_names)
    env = make_env(ONE_DISK_WALK, params=params, backend="direct", seed=params.seed)
    log: list[str] = []
    try:
        trainer = QLearningTrainer(env, ONE_DISK_WALK, params, run, TrainingHooks(log=log.append), resume)
        summary = trainer.train()
    finally:
        env.close()
    return run, summary, log


def selection_rows(run):
    return SelectionLog(run.path).rows()


def test_checks_run_every_few_episodes_and_after_the_last_and_keep_the_best_table(tmp_path):
    params = cube_params()
    run, summary, log = train(tmp_path, params)

    rows = selection_rows(run)
    assert [int(row[0]) for row in rows] == [2, 4, 5]
    scores = [float(row[1]) for row in rows]
    best = max(scores)
    best_episode = int(rows[scores.index(best)][0])
    assert [float(row[3]) for row in rows] == [max(scores[:i + 1]) for i in range(3)]
    assert summary["selection"] == {"checked_at": 5, "best_score": pytest.approx(best), "best_episode": best_episode}
    assert sum("table check after episode" in line for line in log) == 3
    kept = json.loads((run.path / BEST_CHECKPOINT).read_text())
    assert kept["selected"]["episode"] == best_episode and kept["episode"] == best_episode
    assert kept["selected"]["score"] == pytest.approx(best)

    # The kept table, played again on the checks' episodes, scores what its check said: the checks are reproducible.
    env = make_env(ONE_DISK_WALK, params=params, backend="direct", seed=params.seed)
    try:
        episodes = play_greedy(env, QLearn.from_dict(kept["qlearn"]), ONE_DISK_WALK.state_key(params),
                               params.selection, params.nsteps, params.running_step)
    finally:
        env.close()
    assert score(episodes, ONE_DISK_WALK)[0] == pytest.approx(best)
    # evaluate.py plays it: a checkpoint of the run's format, with the run's params beside it.
    assert callable(TrainedRun(run.path / BEST_CHECKPOINT, [ONE_DISK_WALK]).policy(None, 0))


def test_without_selection_nothing_is_checked(tmp_path):
    run, summary, log = train(tmp_path, cube_params(every=0, nepisodes=3))
    assert not (run.path / "selection.csv").exists() and not (run.path / BEST_CHECKPOINT).exists()
    assert "selection" not in summary and not any("table check" in line for line in log)


def test_the_vector_trainer_refuses_checks_before_it_writes(tmp_path):
    params = cube_params()
    run = RunDirectory.create(tmp_path, "moving_cube", params.to_mapping(), ONE_DISK_WALK.metric_names)
    before = sorted(path.name for path in run.path.iterdir())
    env = make_vector_env(ONE_DISK_WALK, 2, backend="direct", seed=params.seed, params=params)
    try:
        with pytest.raises(ValueError, match="selection/every 2: the table checks play one env; the 2 envs"):
            VectorQLearningTrainer(env, ONE_DISK_WALK, params, run)
    finally:
        env.close()
    assert sorted(path.name for path in run.path.iterdir()) == before


def test_a_check_plays_the_same_episodes_and_leaves_the_learner_as_it_was(tmp_path):
    params = cube_params()
    env = make_env(ONE_DISK_WALK, params=params, backend="direct", seed=params.seed)
    try:
        qlearn = QLearn(actions=range(env.action_space.n), epsilon=0.5, alpha=0.1, gamma=0.9, seed=3)
        qlearn.q = {("0", 1): 2.0}
        before = qlearn.to_dict()
        key = ONE_DISK_WALK.state_key(params)
        first = play_greedy(env, qlearn, key, params.selection, params.nsteps, params.running_step)
        env.reset(seed=123)  # a training episode between two checks
        env.step(env.action_space.sample())
        second = play_greedy(env, qlearn, key, params.selection, params.nsteps, params.running_step)
    finally:
        env.close()
    assert qlearn.to_dict() == before
    assert len(first) == params.selection.episodes
    assert [(e.steps, e.return_) for e in first] == [(e.steps, e.return_) for e in second]


def test_a_resumed_run_goes_on_checking_against_the_best_it_had(tmp_path):
    run, first, _ = train(tmp_path, cube_params(nepisodes=2))
    assert [int(row[0]) for row in selection_rows(run)] == [2]
    run, summary, log = train(tmp_path, cube_params(nepisodes=4), resume=True, run=RunDirectory(run.path))
    rows = selection_rows(run)
    assert [int(row[0]) for row in rows] == [2, 4]
    assert summary["selection"]["best_score"] == pytest.approx(max(float(row[1]) for row in rows))
    assert summary["selection"]["best_score"] >= first["selection"]["best_score"]


class CtrlCInSecondCheck(gymnasium.Wrapper):
    """Ctrl-C in the first step after the second reset seeded with the checks' seed (77): mid-check."""

    def __init__(self, env):
        super().__init__(env)
        self.check_resets, self.armed = 0, False

    def reset(self, *, seed=None, options=None):
        if seed == 77:
            self.check_resets += 1
            self.armed = self.check_resets == 2
        return self.env.reset(seed=seed, options=options)

    def step(self, action):
        if self.armed:
            raise KeyboardInterrupt
        return self.env.step(action)


def test_a_run_stopped_during_a_check_plays_that_check_again_on_resume(tmp_path):
    params = cube_params(nepisodes=4)
    run = RunDirectory.create(tmp_path, "moving_cube", params.to_mapping(), ONE_DISK_WALK.metric_names)
    env = CtrlCInSecondCheck(make_env(ONE_DISK_WALK, params=params, backend="direct", seed=params.seed))
    try:
        trainer = QLearningTrainer(env, ONE_DISK_WALK, params, run, TrainingHooks(log=lambda line: None))
        with pytest.raises(KeyboardInterrupt):
            trainer.train()
    finally:
        env.close()
    saved = json.loads(run.qtable_json.read_text())
    assert saved["episode"] == 4 and saved["selection"]["checked_at"] == 2
    assert [int(row[0]) for row in selection_rows(run)] == [2]
    run, summary, log = train(tmp_path, params, resume=True, run=RunDirectory(run.path))
    assert [int(row[0]) for row in selection_rows(run)] == [2, 4]
    assert summary["episodes"] == 4 and summary["selection"]["checked_at"] == 4
    assert [line.split(":")[0] for line in log if line.startswith("EP:")] == []  # no training episode re-run


def test_a_resume_with_other_selection_params_is_refused(tmp_path):
    run, _, _ = train(tmp_path, cube_params(nepisodes=2))
    files = {path.name: path.read_bytes() for path in run.path.iterdir() if path.is_file()}
    with pytest.raises(ValueError, match=r"qtable.json: not a usable checkpoint: its table checks ran with selection "
                                         r"\(episodes 3, every 2, seed 77\), this run's is \(episodes 5, every 2, "
                                         r"seed 77\)"):
        train(tmp_path, cube_params(nepisodes=4, episodes=5), resume=True, run=RunDirectory(run.path))
    assert {path.name: path.read_bytes() for path in run.path.iterdir() if path.is_file()} == files


def test_the_checks_rows_after_the_checkpoint_are_dropped_on_resume(tmp_path):
    log = SelectionLog(tmp_path)
    log.write([[2, 1.0, 0.5, 1.0, 2], [4, 2.0, 0.5, 2.0, 4]])
    log.keep_until(3)
    assert [row[0] for row in log.rows()] == ["2"]
    (tmp_path / "selection.csv").write_text("a,b\n")
    with pytest.raises(ValueError, match="selection.csv: not a selection log"):
        log.rows()


@pytest.mark.parametrize("episode, due", [(0, False), (1, False), (2, True), (3, False), (4, False), (5, True)])
def test_a_check_is_due_on_multiples_of_every_and_the_last_episode_once(episode, due):
    # every 2, 5 episodes, 4 already checked
    assert check_due(TableSelection(every=2), SelectionState(checked_at=4 if episode > 2 else 0), episode, 5) is due


@pytest.mark.parametrize("values", [{"checked_at": 2, "best_score": 1.0, "best_episode": 4},
                                    {"checked_at": "2", "best_score": 1.0, "best_episode": 2},
                                    {"checked_at": 2, "best_score": "high", "best_episode": 2}])
def test_a_bad_selection_state_is_refused(values):
    with pytest.raises(ValueError, match="selection"):
        SelectionState.from_dict(values)


def test_no_check_yet_round_trips():
    state = SelectionState()
    assert SelectionState.from_dict(state.to_dict()) == state and state.best_score == -math.inf


def test_the_kept_table_ships_as_the_policy_s_qtable_with_the_checks_log(tmp_path):
    from workspace_tools.ship import ship_run
    run, summary, _ = train(tmp_path, cube_params())
    destination = tmp_path / "policies" / "kept"
    names = ship_run(run.path / BEST_CHECKPOINT, destination)
    assert sorted(names) == sorted(path.name for path in destination.iterdir()) == \
        ["episodes.csv", "learning_curve.png", "params.yaml", "qtable.json", "selection.csv", "summary.json"]
    assert (destination / "qtable.json").read_bytes() == (run.path / BEST_CHECKPOINT).read_bytes()
    assert (destination / "selection.csv").read_bytes() == (run.path / "selection.csv").read_bytes()
    shipped = TrainedRun(destination, [ONE_DISK_WALK])
    assert json.loads((destination / "qtable.json").read_text())["selected"]["episode"] == \
        summary["selection"]["best_episode"] and callable(shipped.policy(None, 0))

    (run.path / "selection.csv").unlink()
    with pytest.raises(ValueError, match="not a run folder \\(missing selection.csv\\)"):
        ship_run(run.path / BEST_CHECKPOINT, tmp_path / "policies" / "other")
    assert not (tmp_path / "policies" / "other").exists()
