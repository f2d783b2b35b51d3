"""Stable-Baselines3 on our envs without a master (direct backend): SB3's check_env on every task, the
VecEnv contract of RobotVecEnv (N worker processes), DQN and PPO training that writes every results file,
resume from model.zip's weights and agent.json's counters, evaluation of a deep run, and which agent
may act in which action space (SAC: Box only, DQN: Discrete only), and PPO's observations normalised in its
network (normalise_observations: the statistics of every rollout, kept in model.zip)."""
import hashlib
import json
import zipfile

import gymnasium
import numpy as np
import pytest
import torch
from stable_baselines3 import DQN
from stable_baselines3.common.env_checker import check_env
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.vec_env import VecCheckNan, VecMonitor

from hopper_training import TASKS as HOPPER_TASKS
from moving_cube_training import TASKS as CUBE_TASKS
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import (
    DEEP_CHECKPOINT,
    DeepPolicy,
    DeepTrainer,
    EpisodeSchedule,
    ParamError,
    RunDirectory,
    TrainedRun,
    TrainingHooks,
    build_model,
    evaluate,
    find_agent,
    make_env,
    make_vec_env,
    worker_seeds,
)
from robot_rl.agents.sb3.normaliser import RunningNormaliser
from workspace_tools.ship import ship_run

pytestmark = pytest.mark.deep  # needs torch and Stable-Baselines3 (requirements-deep.txt)


@pytest.mark.parametrize("task", [*CUBE_TASKS, *HOPPER_TASKS], ids=lambda t: t.env_id)
def test_sb3_check_env_passes_on_every_task(task):
    env = make_env(task, backend="direct")
    try:
        check_env(env.unwrapped, warn=True)
    finally:
        env.close()


def cube_params(**changes):
    return ONE_DISK_WALK.default_params().with_changes("test", **{"nsteps": 8, **changes})


def test_vec_env_contract_with_sb3_wrappers():
    venv = VecMonitor(VecCheckNan(make_vec_env(ONE_DISK_WALK, 2, "direct", 0, cube_params()), raise_exception=True))
    try:
        assert venv.seed(11) == worker_seeds(11, 2)
        observations = venv.reset()
        assert observations.shape == (2, 6) and observations.dtype == np.float32
        dones_seen = 0
        for _ in range(20):
            venv.step_async(np.array([0, 3]))
            observations, rewards, dones, infos = venv.step_wait()
            assert observations.shape == (2, 6) and rewards.shape == (2,) and dones.dtype == np.bool_
            for i in np.flatnonzero(dones):
                dones_seen += 1
                assert infos[i]["terminal_observation"].shape == (6,)
                assert infos[i]["TimeLimit.truncated"] == (infos[i]["episode"]["l"] == 8 and not infos[i]["fell"])
                assert "y_travelled" in infos[i], "the episode's last info (the task's) comes with it"
        assert dones_seen >= 4
        assert venv.get_attr("running_step") == [0.06, 0.06]
        assert venv.env_method("_settle_time", indices=[1]) == [0.15]
        venv.set_attr("custom_mark", 5, indices=0)
        assert venv.get_attr("custom_mark", indices=[0]) == [5]
    finally:
        venv.close()


def test_the_same_seed_gives_the_same_first_observations():
    firsts = []
    for _ in range(2):
        venv = make_vec_env(ONE_DISK_WALK, 2, "direct", 4, cube_params())
        try:
            venv.seed(4)
            firsts.append(venv.reset())
        finally:
            venv.close()
    np.testing.assert_array_equal(*firsts)


def test_agent_params_are_validated_with_one_line_naming_the_key(tmp_path):
    dqn = find_agent("dqn")
    assert dqn.load_params().hidden_units == 64
    bad = tmp_path / "dqn.yaml"
    bad.write_text((dqn.load_params().to_mapping() | {"batch_size": 0}).__repr__().replace("'", '"'))
    with pytest.raises(ParamError, match=f"{bad}: parameter 'batch_size' = 0 out of range"):
        dqn.load_params(bad)
    with pytest.raises(ParamError, match="unknown agent 'a2c'"):
        find_agent("a2c")


def test_episode_schedule_falls_over_its_share_of_the_episodes():
    schedule = EpisodeSchedule(1.0, 0.1, 0.5)
    values = []
    for progress in (0.0, 0.25, 0.5, 0.9):
        schedule.progress = progress
        values.append(schedule(1.0))
    assert values == pytest.approx([1.0, 0.55, 0.1, 0.1])


def train(tmp_path, agent, envs, resume=False, nepisodes=6, max_steps=None, log=None, trainers=None, **agent_changes):
    params = cube_params(nepisodes=nepisodes)
    run = RunDirectory.latest(tmp_path, "moving_cube-" + agent, DEEP_CHECKPOINT) if resume else \
        RunDirectory.create(tmp_path, "moving_cube-" + agent, params.to_mapping(), ONE_DISK_WALK.metric_names,
                            checkpoint_name=DEEP_CHECKPOINT)
    changes = {"learning_starts": 10} if agent == "dqn" else {"n_steps": 16, "batch_size": 16}
    changes |= agent_changes
    agent_params = find_agent(agent).load_params().with_changes("test", **changes)
    env = make_vec_env(ONE_DISK_WALK, envs, "direct", params.seed, params) if envs > 1 else \
        make_env(ONE_DISK_WALK, params=params, backend="direct", seed=params.seed)
    lines = [] if log is None else log
    trainer = DeepTrainer(env, ONE_DISK_WALK, params, find_agent(agent), agent_params, run,
                          TrainingHooks(log=lines.append, checkpoint_every=2), resume=resume, max_steps=max_steps,
                          agent_config=find_agent(agent).config_for(ONE_DISK_WALK))
    if trainers is not None:
        trainers.append(trainer)
    try:
        return run, trainer.train()
    finally:
        env.close()


@pytest.mark.parametrize(("agent", "envs"), [("dqn", 1), ("ppo", 2)])
def test_a_deep_run_writes_every_results_file(tmp_path, agent, envs, monkeypatch):
    # SB3's default logger would make a folder under SB3_LOGDIR (else /tmp/SB3-<date>) at every learn().
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "sb3_log"))
    log = []
    run, summary = train(tmp_path, agent, envs, log=log)
    assert not (tmp_path / "sb3_log").exists(), "SB3's logger wrote a folder"
    for name in ("episodes.csv", "params.yaml", "learning_curve.png", "summary.json", "model.zip", "agent.json"):
        assert (run.path / name).is_file(), name
    records = run.read_episodes()
    assert [r.episode for r in records] == list(range(1, 7))
    assert all(1 <= r.steps <= 8 for r in records)
    assert set(records[0].metrics) == {"y_distance", "success"}
    assert summary["completed"] and summary["episodes"] == 6 and summary["agent"] == agent
    assert summary["env_steps"] >= sum(r.steps for r in records)
    checkpoint = json.loads((run.path / "agent.json").read_text())
    assert (checkpoint["episode"], checkpoint["agent"], checkpoint["envs"]) == (6, agent, envs)
    tuned = str(find_agent(agent).task_config_path(ONE_DISK_WALK))
    assert summary["agent_config"] == checkpoint["agent_config"] == tuned, "the run names the file of its params"
    assert sum(line.startswith("EP: ") for line in log) == 6
    if envs > 1:
        assert any(" - env 2/2 (episodes per env: " in line for line in log)
    if agent == "dqn":
        assert all(0.0 <= r.epsilon <= 1.0 for r in records) and records[-1].epsilon < records[0].epsilon


def test_resume_continues_from_the_weights_and_counters(tmp_path):
    run, first = train(tmp_path, "dqn", 1, nepisodes=4)
    weights = DQN.load(run.model_zip).q_net.state_dict()  # a test may unpickle its own file
    log = []
    _, second = train(tmp_path, "dqn", 1, resume=True, nepisodes=8, log=log)
    assert log[0].startswith(f"Resuming {run.path} after episode 4 ({first['env_steps']} env steps)")
    assert [r.episode for r in run.read_episodes()] == list(range(1, 9))
    assert second["completed"] and second["env_steps"] > first["env_steps"]
    resumed = build_model(find_agent("dqn").load_params(), make_env(ONE_DISK_WALK, backend="direct"), 0.95, 0)
    resumed.set_parameters(str(run.model_zip))
    assert any(not np.array_equal(weights[k].numpy(), v.numpy()) for k, v in resumed.q_net.state_dict().items()), \
        "the resumed run trained on"


def test_resume_refuses_another_agents_checkpoint(tmp_path):
    run, _ = train(tmp_path, "dqn", 1, nepisodes=2)
    checkpoint = json.loads((run.path / "agent.json").read_text())
    checkpoint["agent"] = "ppo"
    (run.path / "agent.json").write_text(json.dumps(checkpoint))
    with pytest.raises(ValueError, match="agent.json: not a usable checkpoint: it is of agent 'ppo', this run "
                                         "trains 'dqn'"):
        train(tmp_path, "dqn", 1, resume=True, nepisodes=4)


def test_reward_scale_scales_what_the_agent_learns_from_not_the_run_s_returns(tmp_path):
    """Before learning_starts DQN acts at random from its seed: both runs see the same episodes."""
    returns, trainers = [], []
    for scale in (1.0, 0.001):
        run, _ = train(tmp_path / str(scale), "dqn", 1, nepisodes=3, trainers=trainers, reward_scale=scale,
                       learning_starts=1000)
        returns.append([r.return_ for r in run.read_episodes()])
    assert returns[1] == pytest.approx(returns[0], rel=1e-5) and any(abs(r) > 1 for r in returns[0])
    buffers = [t.model.replay_buffer for t in trainers]
    stored = [b.rewards[:b.pos].ravel() for b in buffers]
    np.testing.assert_allclose(stored[1], stored[0] * 0.001, rtol=1e-5)


def test_a_checkpoint_from_before_reward_scale_resumes_and_another_scale_is_refused(tmp_path):
    run, _ = train(tmp_path, "dqn", 1, nepisodes=2)
    agent_json = run.path / "agent.json"
    checkpoint = json.loads(agent_json.read_text())
    del checkpoint["agent_params"]["reward_scale"]
    agent_json.write_text(json.dumps(checkpoint))
    refusal = r"agent.json: not a usable checkpoint: its agent params differ from this run's \(reward_scale 1.0 there"
    with pytest.raises(ValueError, match=refusal + r", 0.5 here\)"):
        train(tmp_path, "dqn", 1, resume=True, nepisodes=4, reward_scale=0.5)
    _, summary = train(tmp_path, "dqn", 1, resume=True, nepisodes=4)
    assert summary["completed"] and [r.episode for r in run.read_episodes()] == [1, 2, 3, 4]


def test_a_step_budget_ends_training_and_drives_dqn_exploration(tmp_path):
    run, summary = train(tmp_path, "dqn", 1, nepisodes=1000, max_steps=40)
    assert summary["env_steps"] == 40 and summary["completed"] and summary["episodes"] < 1000


def test_evaluate_runs_the_deep_policy_greedily(tmp_path):
    run, _ = train(tmp_path, "dqn", 1)
    trained = TrainedRun(run.path, list(CUBE_TASKS))
    assert trained.agent is find_agent("dqn") and trained.agent.needs_deep
    reports = [evaluate(trained, episodes=2, horizon_s=0.6, backend="direct", seed=3) for _ in range(2)]
    assert reports[0] == reports[1], "a deterministic policy on the direct backend repeats"
    assert set(reports[0]["greedy"]) == {"mean_return", "mean_y_distance", "success_rate"}


def _append_an_episode_after_the_checkpoint(run):
    """As a trainer killed after its last checkpoint leaves it: a row a resume would drop."""
    with open(run.episodes_csv, "a") as f:
        f.write(run.episodes_csv.read_text().splitlines()[-1].replace("4,", "5,", 1) + "\n")


@pytest.mark.parametrize("damage, expected", [
    ("truncated", "not the model.zip this run's checkpoint recorded (its sha256 differs"),
    ("truncated_with_its_digest", "not weights of this run's dqn model: ValueError: Error: the file"),
    ("another_agents", "not weights of this run's dqn model: "),
    ("another_runs", "not the model.zip this run's checkpoint recorded"),
])
def test_a_deep_resume_checks_model_zip_before_any_file_changes(tmp_path, damage, expected):
    import hashlib
    run, _ = train(tmp_path / "run", "dqn", 1, nepisodes=4)
    _append_an_episode_after_the_checkpoint(run)
    model_zip, agent_json = run.path / "model.zip", run.path / "agent.json"
    if damage.startswith("truncated"):
        model_zip.write_bytes(model_zip.read_bytes()[:2000])
    else:
        other, _ = train(tmp_path / "other", "ppo" if damage == "another_agents" else "dqn", 1, nepisodes=2)
        model_zip.write_bytes((other.path / "model.zip").read_bytes())
    if damage in ("truncated_with_its_digest", "another_agents"):  # as a checkpoint written before digests
        checkpoint = json.loads(agent_json.read_text())
        checkpoint["model_sha256"] = hashlib.sha256(model_zip.read_bytes()).hexdigest()
        agent_json.write_text(json.dumps(checkpoint))
    before = {p.name: p.read_bytes() for p in run.path.iterdir()}
    with pytest.raises(ValueError) as refused:
        train(tmp_path / "run", "dqn", 1, resume=True, nepisodes=8)
    message = str(refused.value)
    assert message.startswith(f"{model_zip.resolve()}: ") or message.startswith(f"{model_zip}: "), message
    assert expected in message and "\n" not in message and "weights_only" not in message, message
    assert {p.name: p.read_bytes() for p in run.path.iterdir()} == before, "no file of the run may change"
    assert [r.episode for r in run.read_episodes()] == [1, 2, 3, 4, 5]


def test_a_checkpoint_cut_short_before_its_model_zip_was_renamed_resumes(tmp_path):
    """agent.json written, model.partial.zip not yet model.zip (a kill in between): resume completes it."""
    run, _ = train(tmp_path, "dqn", 1, nepisodes=4)
    model_zip, partial = run.path / "model.zip", run.path / "model.partial.zip"
    model_zip.rename(partial)
    model_zip.write_bytes(b"the previous checkpoint's model")
    _, summary = train(tmp_path, "dqn", 1, resume=True, nepisodes=6)
    assert summary["completed"] and not partial.exists()
    assert [r.episode for r in run.read_episodes()] == list(range(1, 7))


def test_a_full_disk_during_a_deep_run_leaves_no_partial_model_and_a_summary(tmp_path, monkeypatch):
    """The second checkpoint's model.save fails half written (ENOSPC): no model.partial.zip is left, the
    small summary.json says how the run ended, and the first checkpoint still resumes."""
    import errno
    saves = []
    real_save = DQN.save

    def save(self, path, *args, **kwargs):
        saves.append(path)
        if len(saves) >= 2:
            with open(path, "wb") as f:
                f.write(b"half a model")
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real_save(self, path, *args, **kwargs)
    monkeypatch.setattr(DQN, "save", save)
    with pytest.raises(OSError, match="No space left on device"):
        train(tmp_path, "dqn", 1, nepisodes=6)
    run = RunDirectory.latest(tmp_path, "moving_cube-dqn", DEEP_CHECKPOINT)
    assert not (run.path / "model.partial.zip").exists()
    summary = json.loads(run.summary_json.read_text())
    assert summary["completed"] is False and "No space left on device" in summary["stopped"]
    assert json.loads((run.path / "agent.json").read_text())["episode"] == 2
    monkeypatch.setattr(DQN, "save", real_save)
    _, resumed = train(tmp_path, "dqn", 1, resume=True, nepisodes=6)
    assert resumed["completed"] and [r.episode for r in run.read_episodes()] == list(range(1, 7))


def test_a_buffer_larger_than_the_memory_is_refused_in_one_line(tmp_path):
    params = cube_params()
    run = RunDirectory.create(tmp_path, "moving_cube-dqn", params.to_mapping(), ONE_DISK_WALK.metric_names,
                              checkpoint_name=DEEP_CHECKPOINT)
    agent_params = find_agent("dqn").load_params().with_changes("test", buffer_size=10**9)
    env = make_env(ONE_DISK_WALK, params=params, backend="direct")
    try:
        with pytest.raises(ValueError, match=r"the agent's buffer needs [\d.]+ GiB, more than the .* GiB of memory "
                                             r"available: lower buffer_size"):
            DeepTrainer(env, ONE_DISK_WALK, params, find_agent("dqn"), agent_params, run)
    finally:
        env.close()


@pytest.mark.parametrize(("agent", "env_id", "expected"), [
    ("sac", None, r"^agent sac on MovingCubeOneDiskWalk-v0: SAC needs Box \(continuous\) actions, the task has "
                  r"Discrete\(5\) \(try agent:=dqn or ppo, or a task with continuous actions\)$"),
    ("dqn", "Pendulum-v1", r"^agent dqn on MovingCubeOneDiskWalk-v0: DQN needs Discrete actions, the task has "
                           r"Box\(-2.0, 2.0, \(1,\), float32\) \(try agent:=sac or ppo\)$"),
])
def test_an_agent_that_cannot_act_in_the_task_s_space_is_refused_before_any_file(tmp_path, agent, env_id, expected):
    params = cube_params(nepisodes=2)
    env = gymnasium.make(env_id) if env_id else make_env(ONE_DISK_WALK, params=params, backend="direct")
    run = RunDirectory(tmp_path, "refused")
    try:
        with pytest.raises(ParamError, match=expected):
            DeepTrainer(env, ONE_DISK_WALK, params, find_agent(agent), find_agent(agent).load_params(), run)
    finally:
        env.close()
    assert not run.path.exists() or not any(run.path.iterdir())


def test_sac_learns_on_a_box_space_and_its_greedy_action_is_an_array_in_the_space():
    env = gymnasium.make("Pendulum-v1")
    params = find_agent("sac").load_params().with_changes("test", learning_starts=20, batch_size=16)
    model = build_model(params, env, 0.99, 0)
    assert model.ent_coef == "auto_0.1", "learn_ent_coef: SB3's automatic entropy coefficient from ent_coef"
    model.learn(total_timesteps=40)
    action = DeepPolicy(model)(env.reset(seed=0)[0])
    assert isinstance(action, np.ndarray) and action.dtype == np.float32 and env.action_space.contains(action)
    env.close()


def test_a_shipped_deep_run_keeps_only_the_weights_and_acts_as_the_run(tmp_path):
    run, _ = train(tmp_path, "dqn", 1)
    shipped = tmp_path / "policies" / "demo"
    names = ship_run(run.path, shipped)
    assert sorted(names) == sorted(p.name for p in shipped.iterdir())
    with zipfile.ZipFile(shipped / "model.zip") as model:
        entries = model.namelist()
    assert "data" not in entries and "policy.pth" in entries and all(
        e.endswith(".pth") or e == "_stable_baselines3_version" for e in entries)
    checkpoint = json.loads((shipped / "agent.json").read_text())
    assert checkpoint["model_sha256"] == hashlib.sha256((shipped / "model.zip").read_bytes()).hexdigest()
    reports = [evaluate(TrainedRun(path, list(CUBE_TASKS)), episodes=2, horizon_s=0.6, backend="direct", seed=3)
               for path in (run.path, shipped)]
    assert reports[0] == reports[1]


def test_shipping_refuses_a_folder_that_is_not_a_finished_run(tmp_path):
    run, _ = train(tmp_path, "dqn", 1)
    (run.path / "model.zip").unlink()
    with pytest.raises(ValueError, match="agent.json without its model.zip"):
        ship_run(run.path, tmp_path / "shipped")
    with pytest.raises(ValueError, match="not a run folder"):
        ship_run(tmp_path, tmp_path / "shipped")


def test_the_statistics_are_those_of_every_observation_folded_in():
    normaliser = RunningNormaliser(gymnasium.spaces.Box(-np.inf, np.inf, (3,), np.float32))
    rng = np.random.default_rng(0)
    batches = [rng.normal([0.02, 5.0, -1.0], [0.01, 8.0, 0.5], (n, 3)) for n in (40, 1, 300)]
    for batch in batches:
        normaliser.update(batch)
    seen = np.concatenate(batches)
    np.testing.assert_allclose(normaliser.mean.numpy(), seen.mean(axis=0), rtol=1e-5)
    # the start's variance 1 weighs 1e-4 of an observation: 3e-7 over these 341
    np.testing.assert_allclose(normaliser.var.numpy(), seen.var(axis=0), rtol=1e-5, atol=1e-6)
    normalised = normaliser(torch.as_tensor(seen, dtype=torch.float32)).numpy()
    np.testing.assert_allclose(normalised.mean(axis=0), 0.0, atol=1e-4)
    np.testing.assert_allclose(normalised.std(axis=0), 1.0, rtol=5e-3)  # the start and the floor: 0.16 %
    far = normaliser(torch.tensor([[1e6, -1e6, 0.0]])).numpy()
    assert far[0, 0] == 10.0 and far[0, 1] == -10.0, "clipped to +/- 10, VecNormalize's bound"


def test_at_the_start_the_normaliser_is_the_identity():
    normaliser = RunningNormaliser(gymnasium.spaces.Box(-1.0, 1.0, (2, 2), np.float32))
    observations = torch.tensor([[[0.5, -0.25], [1.0, 0.0]]])
    np.testing.assert_allclose(normaliser(observations).numpy(), [[0.5, -0.25, 1.0, 0.0]], rtol=1e-6)


def test_a_run_keeps_its_statistics_in_model_zip_and_its_resume_and_policy_use_them(tmp_path):
    trainers = []
    run, first = train(tmp_path, "ppo", 1, nepisodes=6, trainers=trainers, normalise_observations=True)
    extractor = trainers[0].model.policy.features_extractor
    assert isinstance(extractor, RunningNormaliser)
    folded = float(extractor.count)
    assert folded >= 16 and (folded - 1e-4) % 16 == pytest.approx(0.0, abs=1e-6), "whole rollouts of 16 steps"
    assert np.any(extractor.mean.numpy() != 0.0)
    saved = load_from_zip_file(str(run.model_zip), device="cpu", load_data=False)[1]["policy"]
    assert saved["features_extractor.count"] >= 16, "model.zip holds the statistics"
    env = make_env(ONE_DISK_WALK, backend="direct")
    try:
        played = TrainedRun(run.path, list(CUBE_TASKS)).policy(env, 0).model.policy.features_extractor
    finally:
        env.close()
    for name in ("mean", "var", "count"):
        assert torch.equal(getattr(played, name), saved[f"features_extractor.{name}"]), name
    _, second = train(tmp_path, "ppo", 1, resume=True, nepisodes=12, trainers=trainers, normalise_observations=True)
    resumed = trainers[1].model.policy.features_extractor
    assert float(resumed.count) > folded, "the resumed run folds its rollouts into the saved statistics"
    assert second["completed"] and second["env_steps"] > first["env_steps"]
