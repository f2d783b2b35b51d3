"""Agent ppo_finetune (issue 39, Track A's RL stage): its actor starts as the shipped bc_dagger student exactly, only
the critic learns in the frozen updates, a tiny run writes every file, resumes from its weights (not the student's),
and evaluate.py plays it; bad params get one line."""
import numpy as np
import pytest
import torch

import hopper_training
from hopper_training.envs.end_to_end import END_TO_END
from hopper_training.teacher.finetune import FinetuneParams, FinetunePPO, load_student, student_folder
from robot_rl import AGENTS, DEEP_CHECKPOINT, ParamError, RunDirectory, TrainingHooks, make_env

pytestmark = pytest.mark.deep  # torch

AGENT = AGENTS["ppo_finetune"]
TINY = dict(n_steps=64, batch_size=32, n_epochs=2, frozen_policy_updates=1)


@pytest.fixture
def env():
    made = make_env(END_TO_END, backend="direct", seed=0)
    yield made
    made.close()


def start(tmp_path, env, resume=False, max_steps=128, **changes):
    params = END_TO_END.default_params()
    if resume:
        run = RunDirectory.latest(tmp_path, AGENT.results_name(END_TO_END), DEEP_CHECKPOINT)
    else:
        run = RunDirectory.create(tmp_path, AGENT.results_name(END_TO_END), params.to_mapping(),
                                  END_TO_END.metric_names, run_name="tiny", checkpoint_name=AGENT.checkpoint_name)
    agent_params = AGENT.load_params().with_changes("test", **{**TINY, **changes})
    return AGENT.make_trainer(env, END_TO_END, params, run, TrainingHooks(log=lambda _line: None), resume=resume,
                              agent_params=agent_params, max_steps=max_steps), run


def actor(model):
    return [p.detach().clone() for p in model.actor_parameters()]


def test_the_config_loads_and_unknown_keys_or_a_missing_student_get_one_line(tmp_path, env):
    params = AGENT.load_params()
    assert isinstance(params, FinetuneParams) and params.algorithm() is FinetunePPO
    kwargs = params.algorithm_kwargs()
    assert kwargs["use_sde"] and kwargs["sde_sample_freq"] == 8 and "student" not in kwargs
    assert student_folder(params).is_dir()
    bad = tmp_path / "bad.yaml"
    bad.write_text(AGENT.config_path.read_text() + "log_std: -3\n")
    with pytest.raises(ParamError, match="log_std"):
        AGENT.load_params(bad)
    with pytest.raises(ParamError, match="^test: ppo_finetune normalises the observations by its student's fixed "):
        AGENT.load_params().with_changes("test", normalise_observations=True)
    missing = AGENT.load_params().with_changes("test", student=str(tmp_path))
    with pytest.raises(ParamError, match=r"^agent ppo_finetune: .*student.json: not a student's architecture"):
        AGENT.check_fit(env, missing, "agent ppo_finetune")


def test_the_actor_starts_as_the_student_and_only_the_critic_learns_while_frozen(tmp_path, env):
    trainer, _ = start(tmp_path, env)
    model = trainer.model
    student = load_student(student_folder(AGENT.load_params()))
    observation, _ = env.reset(seed=5)
    for _ in range(30):
        action, _ = model.predict(observation, deterministic=True)
        np.testing.assert_allclose(action, student(observation), atol=1e-5)
        observation, *_ = env.step(action)
    before, critic = actor(model), [p.detach().clone() for p in model.policy.value_net.parameters()]
    model.learn(total_timesteps=64)  # one update, within the frozen one
    assert all(torch.equal(a, b) for a, b in zip(before, actor(model))), "the actor changed while frozen"
    assert not all(torch.equal(a, b) for a, b in zip(critic, model.policy.value_net.parameters()))
    model.learn(total_timesteps=64, reset_num_timesteps=False)  # past the frozen update: the actor learns
    assert not all(torch.equal(a, b) for a, b in zip(before, actor(model)))


def test_a_tiny_run_writes_every_file_resumes_from_its_own_weights_and_plays(tmp_path, env):
    trainer, run = start(tmp_path, env, max_steps=128)
    summary = trainer.train()
    assert summary["agent"] == "ppo_finetune" and trainer.state.env_steps == 128
    for name in ("params.yaml", "episodes.csv", DEEP_CHECKPOINT, "model.zip", "summary.json"):
        assert (run.path / name).is_file(), name
    trained = actor(trainer.model)
    resumed, _ = start(tmp_path, env, resume=True, max_steps=192)
    assert all(torch.equal(a, b) for a, b in zip(trained, actor(resumed.model))), "resume took the student again"
    resumed.train()
    assert resumed.state.env_steps == 192
    from robot_rl.evaluation import TrainedRun, evaluate
    report = evaluate(TrainedRun(run.path, hopper_training.TASKS), episodes=1, horizon_s=0.2, backend="direct",
                      seed=1000)
    assert report["task"] == "MonopedEndToEnd-v0" and report["greedy"]["mean_time_upright_s"] > 0.0


def test_a_student_that_does_not_fit_is_refused_in_one_line_before_any_file(tmp_path, env):
    """Before a run folder (the registry's fit check), and in the trainer too."""
    narrow = AGENT.load_params().with_changes("test", hidden_units=64)
    with pytest.raises(ParamError, match=r"does not fit hidden_layers 2 x hidden_units 64 and this task's 63 "):
        AGENT.check_fit(env, narrow, "agent ppo_finetune")
    AGENT.check_fit(env, AGENT.load_params(), "agent ppo_finetune")  # the shipped student fits
    with pytest.raises(ParamError, match="do not fit the actor's"):
        start(tmp_path, env, hidden_units=64)
