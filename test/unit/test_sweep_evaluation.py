"""A sweep's trial is evaluated as evaluate.py evaluates by default: on the monoped, from starts leaning
0.02-0.05 rad even when the run trained from upright starts (stay_up, hop)."""
import dataclasses

from hopper_training import TASKS as HOPPER_TASKS
from robot_rl import (
    EVAL_INITIAL_TILT,
    QLearningTrainer,
    RunDirectory,
    TrainedRun,
    TrainingHooks,
    evaluate,
    find_task,
    make_env,
)
from workspace_tools.sweep import TrialJob, _evaluate

STAY_UP = find_task(HOPPER_TASKS, "stay_up")


def test_a_trial_of_an_upright_start_task_is_evaluated_leaning_as_evaluate_py_does(tmp_path):
    params = dataclasses.replace(STAY_UP.default_params(), nepisodes=2, nsteps=10)
    assert (params.initial_tilt.low, params.initial_tilt.high) == (0.0, 0.0), "the task trains upright"
    run = RunDirectory.create(tmp_path, "trial", params.to_mapping(), STAY_UP.metric_names, "seed=0")
    env = make_env(STAY_UP, params=params, backend="direct", seed=params.seed)
    try:
        QLearningTrainer(env, STAY_UP, params, run, TrainingHooks(log=lambda _: None)).train()
    finally:
        env.close()
    job = TrialJob(name="seed=0", seed=0, params={}, sweep_dir=str(run.path.parent), package="hopper_training",
                   task="stay_up", agent="qlearn", results_name="monoped", checkpoint_name="qtable.json",
                   eval_episodes=2, eval_seed=0)
    report = _evaluate(job)
    assert report["initial_tilt"] == list(EVAL_INITIAL_TILT)
    trained = TrainedRun(run.path, HOPPER_TASKS)
    assert report == evaluate(trained, episodes=2, horizon_s=STAY_UP.eval_horizon_s, backend="direct", seed=0,
                              initial_tilt=EVAL_INITIAL_TILT)
