"""Unit tests of the monoped's residual tasks (MonopedResidualInPlace-v0, MonopedResidualForward-v0) on the
direct backend (no ROS master): the action is added to the controller's flight hip targets, the observation
is in the heading frame, the reward, gymnasium's env checker, and the controller's hip_offset hook."""
import dataclasses
import math

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from hopper_training.controller.core import HopController, HopGains, HopInput
from hopper_training.envs.hop_cycle import controller_params
from hopper_training.envs.residual_forward import RESIDUAL_FORWARD
from hopper_training.envs.residual_in_place import RESIDUAL_IN_PLACE
from hopper_training.robot import base_rpy
from hopper_training.scripted_policies import zero_residual
from robot_rl import make_env

PARAMS = RESIDUAL_IN_PLACE.default_params()


@pytest.fixture
def env():
    made = make_env(RESIDUAL_IN_PLACE, params=PARAMS, backend="direct", seed=0)
    yield made
    made.close()


@pytest.mark.parametrize("task", [RESIDUAL_IN_PLACE, RESIDUAL_FORWARD], ids=lambda t: t.name)
def test_gymnasiums_env_checker_passes(task):
    made = make_env(task, backend="direct", seed=0)
    try:
        check_env(made.unwrapped, skip_render_check=True)
        assert made.action_space == gymnasium.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        assert made.observation_space.shape == (10,)
    finally:
        made.close()


def test_the_two_tasks_differ_by_the_commanded_speed_and_the_placement_law_is_off():
    forward = RESIDUAL_FORWARD.default_params()
    assert (PARAMS.target_speed, forward.target_speed) == (0.0, 0.4)
    assert not (PARAMS.neutral_point or PARAMS.speed_feedback or forward.neutral_point or forward.speed_feedback)
    on = controller_params(forward)
    assert on.neutral_point and on.speed_feedback and on.target_speed == 0.4


def test_the_action_is_the_residual_on_the_flight_hips_held_for_the_hop(env):
    unwrapped = env.unwrapped
    env.reset(seed=1)
    env.step(np.zeros(2, dtype=np.float32))
    action = np.array([0.5, -1.0], dtype=np.float32)
    _, _, terminated, _, info = env.step(action)
    assert not terminated
    expected = (0.5 * PARAMS.residual_range, -PARAMS.residual_range)
    assert unwrapped.controller.hip_offset == pytest.approx(list(expected))
    assert info["residual"] == pytest.approx(expected)
    with pytest.raises(ValueError, match="not in"):
        env.step(np.array([1.5, 0.0], dtype=np.float32))


def test_the_observation_is_in_the_heading_frame_and_the_reward_counts_the_speed_error():
    params = RESIDUAL_FORWARD.default_params()
    made = make_env(RESIDUAL_FORWARD, params=params, backend="direct", seed=0)
    try:
        unwrapped = made.unwrapped
        made.reset(seed=2)
        for _ in range(3):
            observation, reward, terminated, _, info = made.step(np.zeros(2, dtype=np.float32))
            assert not terminated
            vx, vy = np.mean(unwrapped.velocities, axis=0)
            _, _, yaw = base_rpy(unwrapped.readings)
            c, s = math.cos(yaw), math.sin(yaw)
            assert observation[0:2] == pytest.approx([c * vx + s * vy, -s * vx + c * vy], abs=1e-5)
            ex = vx - params.target_speed
            assert observation[2:4] == pytest.approx([c * ex + s * vy, -s * ex + c * vy], abs=1e-5)
            assert math.hypot(*observation[0:2]) == pytest.approx(math.hypot(vx, vy), abs=1e-5)
            assert reward == pytest.approx(params.alive_reward * info["hop_time"]
                                           - params.speed_weight * math.hypot(ex, vy), abs=1e-4)
    finally:
        made.close()


def test_do_nothing_is_no_residual_and_refuses_another_speed(env):
    policy = zero_residual(env, 0.0)
    assert np.array_equal(policy(np.zeros(10)), np.zeros(2))
    forward = make_env(RESIDUAL_FORWARD, backend="direct", seed=0)
    try:
        zero_residual(forward, 0.4)
        with pytest.raises(ValueError, match="target_speed"):
            zero_residual(forward, 0.3)
    finally:
        forward.close()


def test_the_hip_offset_is_added_to_the_flight_hips_before_the_swing_gain():
    reading = HopInput(time=1.0, joint_position=(0.0, 0.4, -0.6), joint_velocity=(0.0, 0.0, 0.0),
                       orientation=(0.0, 0.0, 0.0, 1.0), angular_velocity=(0.0, 0.0, 0.0), position=(0.0, 0.0, 1.0),
                       linear_velocity=(0.2, 0.0, 0.0), contact=False)

    def targets(offset):
        controller = HopController(dataclasses.replace(HopGains(), speed_feedback=False, neutral_point=False))
        controller._started = True  # in the air, not the standing start
        controller.hip_offset = list(offset)
        return controller.update(reading)
    base, moved = targets((0.0, 0.0)), targets((0.02, -0.03))
    gain = HopGains().flight_swing_gain
    assert moved[0] - base[0] == pytest.approx(gain * 0.02) and moved[1] - base[1] == pytest.approx(gain * -0.03)
    assert moved[2] == base[2]  # the knee is untouched
