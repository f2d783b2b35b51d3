"""Unit tests for the monoped's action modes (no ROS master): accumulated targets and their clamping at the
URDF limits, the hold action, the continuous targets, the extended observation, on hand-made readings; and
gymnasium's env checker on every mode with the direct backend."""
import dataclasses
from pathlib import Path

import gymnasium
import numpy as np
import pytest
import yaml
from gymnasium.utils.env_checker import check_env
from test_monoped import readings

from hopper_training.actions import HOLD
from hopper_training.envs.hop import HOP
from hopper_training.envs.stay_up import STAY_UP, MonopedEnv
from hopper_training.robot import CONTROLLERS, MONOPED
from pybullet_sim.config import parse_robot_config
from robot_rl import ParamError

from fake_backend import FakeBackend

pytestmark = pytest.mark.deep  # needs torch and Stable-Baselines3 (requirements-deep.txt)

CONFIG = parse_robot_config(yaml.safe_load(Path(MONOPED.sim_config_path).read_text()), "hopper_sim.yaml")
START = STAY_UP.default_params().start_pose
START_TARGETS = [START.haa, START.hfe, START.kfe]
INCREMENT = STAY_UP.default_params().joint_increment_value


def make_env(mode, measured=(0.3, -0.7, -0.2), **overrides):
    """A reset env of action_mode `mode` whose robot always reads joints at `measured`, and its backend."""
    backend = FakeBackend(readings(joints=measured), config=CONFIG)
    env = MonopedEnv(backend=backend, params=dataclasses.replace(STAY_UP.default_params(), action_mode=mode,
                                                                 **overrides))
    env.reset(seed=0)
    return env, backend


def commanded(env, backend, action):
    """The three targets one step of `action` publishes, in haa, hfe, kfe order."""
    backend.commands.clear()
    env.step(action)
    assert [controller for controller, _ in backend.commands] == list(CONTROLLERS)
    return [value for _, value in backend.commands]


def test_the_yamls_default_to_accumulate_with_the_crouch():
    for task in (STAY_UP, HOP):
        p = task.default_params()
        assert p.action_mode == "accumulate" and p.start_pose.kfe == pytest.approx(-0.9)
        assert (p.initial_tilt.low, p.initial_tilt.high) == (0.0, 0.0)


def test_accumulate_starts_at_the_start_pose_and_adds_to_the_last_command_not_the_measured_position():
    env, backend = make_env("accumulate")
    assert env.action_space == gymnasium.spaces.Discrete(7)
    assert backend.commands == list(zip(CONTROLLERS, START_TARGETS))
    assert commanded(env, backend, 0) == pytest.approx([START.haa + INCREMENT, START.hfe, START.kfe])
    assert commanded(env, backend, 0) == pytest.approx([START.haa + 2 * INCREMENT, START.hfe, START.kfe])
    assert commanded(env, backend, 3) == pytest.approx([START.haa + 2 * INCREMENT, START.hfe - INCREMENT, START.kfe])
    assert commanded(env, backend, 5) == pytest.approx([START.haa + 2 * INCREMENT, START.hfe - INCREMENT,
                                                        START.kfe - INCREMENT])


def test_hold_publishes_the_held_targets_again():
    env, backend = make_env("accumulate")
    moved = commanded(env, backend, 2)
    assert commanded(env, backend, HOLD) == moved
    assert commanded(env, backend, HOLD) == moved


@pytest.mark.parametrize("action, joint, limit", [(0, 0, 1.6), (1, 0, -1.6), (2, 1, 1.6), (3, 1, -1.6),
                                                  (4, 2, 0.0), (5, 2, -1.6)])
def test_accumulated_targets_stop_at_the_urdf_limits(action, joint, limit):
    env, backend = make_env("accumulate")
    assert limit in env.joint_limits[joint]  # the URDF's (test_monoped.py: test_joint_limits_are_the_urdfs)
    for _ in range(80):  # 80 x 0.05 = 4 rad: past every limit
        targets = commanded(env, backend, action)
    assert targets[joint] == limit
    back = commanded(env, backend, action ^ 1)  # the other direction leaves the limit at once
    assert back[joint] == pytest.approx(limit - INCREMENT if action % 2 == 0 else limit + INCREMENT)


def test_a_reset_brings_the_commanded_targets_back_to_the_start_pose():
    env, backend = make_env("accumulate")
    for action in (0, 2, 5, 5):
        env.step(action)
    backend.commands.clear()
    env.reset()
    assert backend.commands == list(zip(CONTROLLERS, START_TARGETS))
    assert commanded(env, backend, HOLD) == pytest.approx(START_TARGETS)


def test_tutorial_mode_keeps_the_tutorials_rule_and_straight_start():
    env, backend = make_env("tutorial", measured=(0.3, -0.7, -0.2))
    assert env.action_space == gymnasium.spaces.Discrete(6)
    assert backend.placements == []  # the sim's spawn pose: straight, 5 cm above the ground
    assert backend.commands == list(zip(CONTROLLERS, (0.0, 0.0, 0.0)))
    assert commanded(env, backend, 4) == pytest.approx([0.3, -0.7, -0.15])
    assert commanded(env, backend, 4) == pytest.approx([0.3, -0.7, -0.15])  # measured, not accumulated


def test_targets_mode_maps_minus_one_to_one_about_the_start_pose_and_clamps():
    env, backend = make_env("targets", target_range=1.2)
    assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, (3,), np.float32)
    assert commanded(env, backend, np.zeros(3, np.float32)) == pytest.approx(START_TARGETS)
    assert commanded(env, backend, np.array([0.5, -0.25, 0.5], np.float32)) == \
        pytest.approx([START.haa + 0.6, START.hfe - 0.3, START.kfe + 0.6])
    assert commanded(env, backend, np.array([1.0, 1.0, 1.0], np.float32)) == \
        pytest.approx([START.haa + 1.2, 1.6, 0.0])  # hfe at its upper limit, the knee straight
    with pytest.raises(ValueError, match="not in Box"):
        env.step(np.array([1.5, 0.0, 0.0], np.float32))


def test_extended_observation_adds_velocities_contact_and_the_last_targets():
    env, backend = make_env("accumulate", observation="extended")
    assert env.observation_space.shape == (23,)
    observation, *_ = env.step(5)
    assert observation[:10].tolist() == pytest.approx(env._observe(env.readings)[:10].tolist())
    assert observation[19] == 0.0  # the hand-made robot's foot is in the air
    assert observation[20:].tolist() == pytest.approx([START.haa, START.hfe, START.kfe - INCREMENT], abs=1e-6)


@pytest.mark.parametrize("key, value, message", [
    ("action_mode", "jump", "'action_mode' = 'jump' is not one of accumulate, tutorial, targets"),
    ("observation", "full", "'observation' = 'full' is not one of standard, extended"),
    ("target_range", 0.0, "'target_range' = 0.0 out of range"),
    ("start_pose", {"haa": 0.0, "hfe": 0.5, "kfe": 0.3}, "'start_pose/kfe' = 0.3 is outside the URDF's limits"),
    ("initial_tilt", {"low": 0.05, "high": 0.02}, "'initial_tilt/low' (0.05) must not be above 'initial_tilt/high'"),
    ("initial_tilt", {"low": 0.0, "high": 0.7}, "'initial_tilt/high' = 0.7 out of range"),
])
def test_bad_action_params_name_the_param(key, value, message):
    values = {**STAY_UP.default_params().to_mapping(), key: value}
    with pytest.raises(ParamError) as error:
        STAY_UP.params_type.from_mapping(values, "stay_up.yaml")
    assert str(error.value).startswith("stay_up.yaml: ") and message in str(error.value)


@pytest.mark.parametrize("task", [STAY_UP, HOP], ids=lambda t: t.env_id)
@pytest.mark.parametrize("mode, observation", [("accumulate", "standard"), ("tutorial", "standard"),
                                               ("targets", "extended"), ("accumulate", "extended")])
def test_gymnasiums_env_checker_passes_on_every_mode(task, mode, observation):
    p = task.default_params().with_changes("test", action_mode=mode, observation=observation,
                                           initial_tilt={"low": 0.02, "high": 0.05})
    env = gymnasium.make(task.env_id, backend="direct", params=p)
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


def test_params_of_a_run_from_before_the_action_modes_keep_the_tutorials_rule():
    values = STAY_UP.default_params().to_mapping()
    for key in ("action_mode", "start_pose", "target_range", "observation", "initial_tilt"):
        del values[key]
    old = STAY_UP.params_type.from_mapping(values, "params.yaml")
    assert old.action_mode == "tutorial" and (old.initial_tilt.low, old.initial_tilt.high) == (0.0, 0.0)


def test_a_vector_env_steps_continuous_targets_and_refuses_bad_ones():
    from robot_rl import make_vector_env
    p = STAY_UP.default_params().with_changes("test", action_mode="targets", nsteps=20)
    env = make_vector_env(STAY_UP, 2, backend="direct", seed=0, params=p)
    try:
        first, _ = env.reset(seed=0)
        observations, *_ = env.step(np.array([[0.0, 0.0, 0.5], [0.0, 0.0, -0.5]], np.float32))
        assert observations.shape == first.shape and observations[0, 7] > observations[1, 7]  # the knees
        for actions, expected in (([[0.0, 0.0, 0.0]], "3 action values for 2 envs of Box"),
                                  ([[0, 0, 0], [0, 0, 2.0]], "of env 1")):
            with pytest.raises(ValueError, match=expected):
                env.step(np.array(actions, np.float32))
    finally:
        env.close()


def test_tabular_q_learning_refuses_continuous_actions(tmp_path):
    from robot_rl import QLearningTrainer, RunDirectory
    p = STAY_UP.default_params().with_changes("test", action_mode="targets")
    env, _ = make_env("targets")
    run = RunDirectory.create(tmp_path, "monoped", p.to_mapping())
    with pytest.raises(ValueError, match=r"tabular Q-learning needs Discrete actions, Monoped-v0 has Box"):
        QLearningTrainer(env, STAY_UP, p, run)


@pytest.mark.parametrize("observation", ["standard", "extended"])
def test_stable_baselines3s_env_checker_passes_on_the_continuous_targets(observation):
    env_checker = pytest.importorskip("stable_baselines3.common.env_checker", reason="./ws setup deep installs SB3")
    p = STAY_UP.default_params().with_changes("test", action_mode="targets", observation=observation)
    env = gymnasium.make(STAY_UP.env_id, backend="direct", params=p)
    try:
        env_checker.check_env(env.unwrapped, warn=False)
    finally:
        env.close()
