"""Unit tests of MonopedEndToEnd-v0 (issue 39) on the direct backend: its spaces pass gymnasium's and
Stable-Baselines3's env checkers, the observation stacks `history` frames and the last action, the reward terms on
hand-made values, and the task's termination at 0.6 rad."""
import dataclasses
import math

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from hopper_training.envs.end_to_end import END_TO_END, FRAME_SIZE, reward_terms, tilt_angle
from hopper_training.robot import base_rpy
from robot_rl import make_env

pytestmark = pytest.mark.deep  # imports Stable-Baselines3

PARAMS = END_TO_END.default_params()


@pytest.fixture
def env():
    made = make_env(END_TO_END, params=PARAMS, backend="direct", seed=0)
    yield made
    made.close()


def test_the_spaces_pass_gymnasiums_and_sb3s_checkers(env):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)
    assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
    assert env.observation_space.shape == (PARAMS.history * FRAME_SIZE + 3,)
    assert (PARAMS.history, PARAMS.running_step, PARAMS.max_incl, PARAMS.action_mode) == (4, 0.005, 0.6, "targets")


def test_the_observation_stacks_frames_newest_first_and_the_last_action(env):
    observation, _ = env.reset(seed=3)
    frames = observation[:-3].reshape(PARAMS.history, FRAME_SIZE)
    assert all(np.array_equal(frames[0], f) for f in frames) and np.array_equal(observation[-3:], np.zeros(3))
    action = np.array([0.1, -0.2, 0.3], np.float32)
    second, *_ = env.step(action)
    frames2 = second[:-3].reshape(PARAMS.history, FRAME_SIZE)
    assert np.array_equal(frames2[1], frames[0]) and not np.array_equal(frames2[0], frames[0])
    assert np.array_equal(second[-3:], action)
    third, *_ = env.step(action)
    assert np.array_equal(third[:-3].reshape(PARAMS.history, FRAME_SIZE)[1:3], frames2[:2])


def test_observe_yaw_puts_the_bases_yaw_as_cos_and_sin_between_the_frames_and_the_action():
    params = PARAMS.with_changes("test", observe_yaw=True)
    env = make_env(END_TO_END, params=params, backend="direct", seed=0)
    try:
        check_env(env.unwrapped, skip_render_check=True)
        assert env.observation_space.shape == (PARAMS.history * FRAME_SIZE + 2 + 3,)
        env.reset(seed=3)
        for _ in range(200):  # hop about a little, so that the yaw is not 0
            observation, *_ = env.step(np.array([0.3, -0.2, 0.1], np.float32))
        yaw = base_rpy(env.unwrapped.readings)[2]
        assert abs(yaw) > 1e-4
        assert observation[-5:-3] == pytest.approx([math.cos(yaw), math.sin(yaw)], abs=1e-6)
        assert np.array_equal(observation[-3:], np.array([0.3, -0.2, 0.1], np.float32))
    finally:
        env.close()


def test_the_reward_terms_on_hand_made_values():
    p = PARAMS
    still = np.zeros(3)
    upright = reward_terms(p, 0.0, None, still, still)
    assert upright == {"alive": p.alive_reward, "upright": p.upright_weight, "hop": 0.0, "action_rate": 0.0,
                       "speed": 0.0, "lateral": 0.0}
    leaning = reward_terms(p, 0.3, None, still, still)
    assert leaning["upright"] == pytest.approx(p.upright_weight * math.exp(-0.09 / p.upright_scale))
    assert reward_terms(p, 0.0, 0.1, still, still)["hop"] == pytest.approx(p.hop_weight * 0.1)
    assert reward_terms(p, 0.0, 5.0, still, still)["hop"] == pytest.approx(p.hop_weight * p.hop_cap_s)  # capped
    jump = reward_terms(p, 0.0, None, np.array([0.5, 0.0, -0.5]), still)
    assert jump["action_rate"] == pytest.approx(-p.action_rate_weight * 0.5)
    assert reward_terms(p, 0.0, None, still, still, 0.5)["speed"] == 0.0, "in place (weight 0) speed is free"
    forward = p.with_changes("test", target_speed=0.4, speed_weight=2.0)
    assert reward_terms(forward, 0.0, None, still, still, 0.4)["speed"] == 0.0
    assert reward_terms(forward, 0.0, None, still, still, 0.1)["speed"] == pytest.approx(-2.0 * 0.09)
    assert reward_terms(p, 0.0, None, still, still, 0.0, 0.5)["lateral"] == 0.0, "in place (weight 0) drift is free"
    drifting = reward_terms(p.with_changes("test", lateral_weight=1.5), 0.0, None, still, still, 0.0, -0.4)
    assert drifting["lateral"] == pytest.approx(-1.5 * 0.16) and drifting["speed"] == 0.0
    assert tilt_angle(0.3, 0.0) == pytest.approx(0.3) and tilt_angle(0.2, 0.2) > 0.2


def test_a_fall_past_0_6_rad_ends_the_episode_with_the_fall_term_alone(env):
    env.reset(seed=0)
    for _ in range(2000):  # a straight leg pushed hard forward: it falls
        _, reward, terminated, truncated, info = env.step(np.array([0.0, 1.0, 1.0], np.float32))
        if terminated or truncated:
            break
    assert terminated and info["fell"]
    assert reward == PARAMS.done_reward and info["reward_fall"] == PARAMS.done_reward


@pytest.mark.parametrize("variant, changes", [
    ("end_to_end_push.yaml", {"push_speed": 0.3, "target_speed": 0.0}),
    ("end_to_end_forward.yaml", {"push_speed": 0.0, "target_speed": 0.4, "observe_yaw": True}),
    ("end_to_end_forward_push.yaml", {"push_speed": 0.3, "target_speed": 0.4, "observe_yaw": True})])
def test_each_variant_config_loads_strictly_with_the_values_its_name_says(variant, changes):
    params = END_TO_END.load_params(END_TO_END.config_path.parent / variant)
    assert {key: getattr(params, key) for key in changes} == changes


def test_the_assist_push_config_is_the_assist_config_with_pushes_alone():
    folder = END_TO_END.config_path.parent
    assist = END_TO_END.load_params(folder / "end_to_end_assist.yaml")
    pushed = END_TO_END.load_params(folder / "end_to_end_assist_push.yaml")
    assert assist.push_speed == 0.0 and pushed == dataclasses.replace(assist, push_speed=0.3)
