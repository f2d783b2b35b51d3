"""Every registered task, the same checks: registration, params, gymnasium's env checker, reward terms
that sum to the reward, metrics and state key, on the direct backend (no ROS master)."""
import dataclasses
import json
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hopper_training
import moving_cube_training
from robot_rl import TASKS, Episode, TrainingState, find_task, make_env, restored_state
from robot_rl.task import play_episode

ALL_TASKS = [*moving_cube_training.TASKS, *hopper_training.TASKS]
IDS = [task.env_id for task in ALL_TASKS]


def test_the_tasks_are_registered():
    assert IDS == ["MovingCubeOneDiskWalk-v0", "Monoped-v0", "MonopedHop-v0", "MonopedHopInPlace-v0",
                   "MonopedResidualInPlace-v0", "MonopedResidualForward-v0", "MonopedEndToEnd-v0"]
    assert all(TASKS[env_id] is task for env_id, task in zip(IDS, ALL_TASKS))
    assert find_task(hopper_training.TASKS, "hop").env_id == "MonopedHop-v0"
    assert find_task(hopper_training.TASKS, "hop_in_place").env_id == "MonopedHopInPlace-v0"
    assert find_task(hopper_training.TASKS, "residual_forward").env_id == "MonopedResidualForward-v0"


def test_a_tasks_former_env_id_still_makes_its_env():
    """MonopedHopLevel-v0, hop_in_place's env id before it was named after its task, is an alias."""
    spec = gymnasium.spec("MonopedHopLevel-v0")
    assert (spec.entry_point, spec.max_episode_steps) == (hopper_training.HOP_IN_PLACE.entry_point, 10000)
    env = gymnasium.make("MonopedHopLevel-v0", backend="direct")
    try:
        assert env.unwrapped.task is hopper_training.HOP_IN_PLACE
    finally:
        env.close()
    # a run made before the rename (its checkpoint names the former id) is still found and resumed
    assert find_task(hopper_training.TASKS, "MonopedHopLevel-v0") is hopper_training.HOP_IN_PLACE
    assert TASKS["MonopedHopLevel-v0"] is hopper_training.HOP_IN_PLACE
    checkpoint = {"format": "f", "task": "MonopedHopLevel-v0", "episode": 0,
                  "state": dataclasses.asdict(TrainingState())}
    assert restored_state(checkpoint, "f", hopper_training.HOP_IN_PLACE).episode == 0
    with pytest.raises(ValueError, match="of task 'MonopedHopLevel-v0'"):
        restored_state(checkpoint, "f", hopper_training.RESIDUAL_IN_PLACE)


@pytest.mark.parametrize("task", ALL_TASKS, ids=IDS)
def test_registered_with_the_default_yamls_nsteps(task):
    params = task.default_params()
    assert isinstance(params, task.params_type)
    assert gymnasium.spec(task.env_id).max_episode_steps == task.max_episode_steps == params.nsteps
    assert task.config_path.name == f"{task.name}.yaml"
    assert task.params_type.from_mapping(params.to_mapping(), "round trip") == params


@pytest.mark.parametrize("task", ALL_TASKS, ids=IDS)
def test_check_env_passes_on_the_direct_backend(task):
    env = gymnasium.make(task.env_id, backend="direct")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()
    # Distances and speeds are unbounded on purpose; anything else the checker says is a failure.
    assert [str(w.message) for w in caught if "infinity" not in str(w.message)] == []


@pytest.mark.parametrize("task", ALL_TASKS, ids=IDS)
def test_reward_terms_in_info_sum_to_the_reward(task):
    env = make_env(task, backend="direct", seed=1, max_episode_steps=100_000)
    rng, space = np.random.default_rng(1), env.action_space
    seen_terms, fell = set(), False
    try:
        env.reset(seed=1)
        for _ in range(20_000):
            action = int(rng.integers(space.n)) if isinstance(space, gymnasium.spaces.Discrete) else \
                rng.uniform(space.low, space.high).astype(space.dtype)
            _, reward, terminated, truncated, info = env.step(action)
            terms = {key: value for key, value in info.items() if key.startswith("reward_")}
            assert terms, "every step names its reward terms"
            assert sum(terms.values()) == pytest.approx(reward, rel=1e-12, abs=1e-9)
            seen_terms |= set(terms)
            fell = fell or terminated
            if terminated or truncated:
                break
    finally:
        env.close()
    assert fell and "reward_fall" in seen_terms and len(seen_terms) >= 3


def test_play_episode_stops_at_max_steps_and_repeats_from_its_seed():
    task = find_task(moving_cube_training.TASKS, "one_disk_walk")
    env = make_env(task, backend="direct", seed=0)
    try:
        def act(observation):
            return 1
        first = play_episode(env, act, 0.1, seed=9, max_steps=3)
        again = play_episode(env, act, 0.1, seed=9, max_steps=3)
    finally:
        env.close()
    assert (first.steps, first.duration) == (3, pytest.approx(0.3)) and not first.terminated
    assert (again.steps, again.return_) == (first.steps, first.return_)


@pytest.mark.parametrize("task", ALL_TASKS, ids=IDS)
def test_metrics_and_state_key(task):
    assert task.headline_metric in task.metric_names
    metrics = task.metrics(Episode(steps=10, return_=1.0, terminated=True, duration=0.5, info={}))
    assert tuple(metrics) == task.metric_names
    params = task.default_params()
    env = make_env(task, params=params, backend="direct")
    try:
        observation, _ = env.reset(seed=0)
    finally:
        env.close()
    state_key = task.state_key(params)
    assert isinstance(state_key.key(observation), str)
    assert json.loads(json.dumps(state_key.to_dict())) == state_key.to_dict()


@pytest.mark.parametrize("call", ["reset", "step", "render"])
def test_an_env_used_after_close_says_so_in_one_line(call):
    """Use after close: gymnasium's ClosedEnvironmentError, not whatever the closed backend raises."""
    env = make_env(moving_cube_training.TASKS[0], backend="direct", render_mode="rgb_array")
    env.reset(seed=0)
    env.close()
    env.close()  # a second close does nothing
    with pytest.raises(gymnasium.error.ClosedEnvironmentError, match="MovingCubeOneDiskWalk-v0: the env is closed"):
        {"reset": lambda: env.reset(), "step": lambda: env.step(0), "render": env.render}[call]()
