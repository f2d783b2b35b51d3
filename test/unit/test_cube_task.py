"""The cube task (MovingCubeOneDiskWalk-v0) on hand-made readings, its state key and its params.

No ROS master and no physics: a fake Backend hands the env the readings each test writes, and
records the wheel commands the env sends.
"""
import dataclasses
import math

import gymnasium
import numpy as np
import pytest
import yaml
from tf.transformations import quaternion_from_euler

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK, MovingCubeOneDiskWalkEnv
from moving_cube_training.params import CubeParams
from moving_cube_training.robot import MOVING_CUBE, ODOMETRY_SENSOR, WHEEL_CONTROLLER
from moving_cube_training.state import CubeStateKey
from pybullet_sim.readings import JointStateReading, OdometryReading
from robot_rl import ParamError, Point, Readings
from robot_rl import make_env as make_task_env

from fake_backend import FakeBackend


def readings(stamp=0.0, y=0.0, roll=0.0, pitch=0.0, yaw=0.0, v_y=0.0, wheel=0.0):
    joints = JointStateReading(stamp=stamp, name=("inertia_wheel_roll_joint",), position=(0.0,),
                               velocity=(wheel,), effort=(0.0,))
    odom = OdometryReading(stamp=stamp, frame_id="world", child_frame_id="cube_body",
                           position=(0.0, y, 0.1), orientation=tuple(quaternion_from_euler(roll, pitch, yaw)),
                           linear_velocity=(0.0, v_y, 0.0), angular_velocity=(0.0, 0.0, 0.0))
    return Readings(joints, {ODOMETRY_SENSOR: odom})


def fake(at_reset=None, script=()):
    return FakeBackend(at_reset or readings(), script)


def params(**overrides):
    return dataclasses.replace(ONE_DISK_WALK.default_params(), **{"reset_settle_time": 0.0, **overrides})


def make_env(backend, **overrides):
    return MovingCubeOneDiskWalkEnv(backend=backend, params=params(**overrides))


# -- reward, termination, truncation --------------------------------------------------------------

def expected_reward(p, dy, v_y, yaw):
    return (dy * p.move_distance_reward_weight + v_y * p.y_linear_speed_reward_weight
            - abs(math.sin(yaw)) * p.y_axis_angle_reward_weight)


def test_reward_is_progress_plus_speed_minus_heading_error():
    p = params(move_distance_reward_weight=1000.0, y_linear_speed_reward_weight=200.0,
               y_axis_angle_reward_weight=50.0)
    backend = fake(at_reset=readings(y=0.25), script=[
        readings(stamp=0.06, y=0.30, v_y=0.4, yaw=0.05),
        readings(stamp=0.12, y=0.28, v_y=-0.1, yaw=-0.02),
    ])
    env = MovingCubeOneDiskWalkEnv(backend=backend, params=p)
    env.reset()
    _, reward, terminated, truncated, info = env.step(2)
    # First step: dy relative to the y at reset. 0.05 * 1000 + 0.4 * 200 - sin(0.05) * 50
    assert reward == pytest.approx(50.0 + 80.0 - math.sin(0.05) * 50.0, abs=1e-3)
    assert reward == pytest.approx(expected_reward(p, 0.05, 0.4, 0.05), abs=1e-3)
    assert (terminated, truncated, info["fell"]) == (False, False, False)
    assert info["y_travelled"] == pytest.approx(0.05)
    _, reward, terminated, _, info = env.step(2)
    # Second step: dy relative to the previous step's y, and |sin(yaw)| for a negative yaw.
    assert reward == pytest.approx(-20.0 - 20.0 - math.sin(0.02) * 50.0, abs=1e-3)
    assert not terminated
    assert info["y_travelled"] == pytest.approx(0.03)


def test_reward_is_relative_to_init_cube_pose_consistently():
    """init_cube_pose/y shifts the observation, not the progress reward."""
    p = params(init_cube_pose=Point(x=0.0, y=1.0, z=0.0))
    backend = fake(at_reset=readings(y=1.1), script=[readings(stamp=0.06, y=1.15)])
    env = MovingCubeOneDiskWalkEnv(backend=backend, params=p)
    observation, _ = env.reset()
    assert observation[1] == pytest.approx(0.1)
    observation, reward, _, _, _ = env.step(2)
    assert observation[1] == pytest.approx(0.15)
    assert reward == pytest.approx(0.05 * p.move_distance_reward_weight, abs=1e-3)


def test_each_reset_restarts_the_progress_reference():
    backend = fake(at_reset=readings(y=0.0), script=[readings(stamp=0.06, y=0.5)])
    env = make_env(backend)
    env.reset()
    env.step(2)
    backend.at_reset = readings(y=0.4)
    backend.script = [readings(stamp=0.06, y=0.41)]
    env.reset()
    _, reward, _, _, info = env.step(2)
    assert reward == pytest.approx(0.01 * env.params.move_distance_reward_weight, abs=1e-3)
    assert info["y_travelled"] == pytest.approx(0.01)


@pytest.mark.parametrize("angles", [
    {"pitch": 0.25}, {"pitch": -0.25}, {"yaw": 0.15}, {"yaw": -0.15}, {"pitch": 0.21, "yaw": 0.0},
], ids=["pitch+", "pitch-", "yaw+", "yaw-", "pitch_just_over"])
def test_tipping_or_turning_away_ends_the_episode_with_the_penalty(angles):
    # Lots of progress in the same step: the fall penalty replaces the shaped reward.
    backend = fake(script=[readings(stamp=0.06, y=0.3, v_y=1.0, **angles)])
    env = make_env(backend)
    env.reset()
    _, reward, terminated, truncated, info = env.step(0)
    assert reward == -env.params.end_episode_points == -1000.0
    assert (terminated, truncated, info["fell"]) == (True, False, True)


@pytest.mark.parametrize("angles", [
    {"pitch": 0.19}, {"pitch": -0.19}, {"yaw": 0.09}, {"yaw": -0.09}, {"pitch": 0.19, "yaw": 0.09},
], ids=["pitch+", "pitch-", "yaw+", "yaw-", "both"])
def test_just_under_the_limits_is_not_a_fall(angles):
    backend = fake(script=[readings(stamp=0.06, **angles)])
    env = make_env(backend)
    env.reset()
    _, reward, terminated, truncated, info = env.step(2)
    assert (terminated, truncated, info["fell"]) == (False, False, False)
    assert reward == pytest.approx(expected_reward(env.params, 0.0, 0.0, angles.get("yaw", 0.0)), abs=1e-3)


def test_truncated_not_terminated_after_nsteps():
    backend = fake()
    env = make_task_env(ONE_DISK_WALK, params=params(nsteps=3), backend=backend)
    env.reset()
    flags = [env.step(2)[2:4] for _ in range(3)]
    assert flags == [(False, False), (False, False), (False, True)]
    env.reset()
    assert env.step(2)[2:4] == (False, False), "reset starts the step count again"


def test_a_fall_on_the_last_step_is_terminated():
    """gymnasium's TimeLimit also reports truncated then; terminated is what stops bootstrapping."""
    backend = fake(script=[readings(stamp=0.06), readings(stamp=0.12, pitch=0.5)])
    env = make_task_env(ONE_DISK_WALK, params=params(nsteps=2), backend=backend)
    env.reset()
    env.step(2)
    assert env.step(2)[2] is True


def test_each_step_advances_running_step_of_sim_time():
    backend = fake()
    env = make_env(backend, running_step=0.06)
    env.reset()
    env.step(2)
    env.step(2)
    assert backend.steps == [60, 60]


def test_settle_time_is_one_step_with_the_reset_command_before_the_first_observation():
    backend = fake(at_reset=readings(y=5.0), script=[readings(stamp=0.3, y=0.2, wheel=3.0)])
    env = make_env(backend, reset_settle_time=0.3, init_roll_vel=7.0)
    observation, info = env.reset()
    assert backend.steps == [300]
    assert backend.commands == [(WHEEL_CONTROLLER, 7.0)]
    assert observation[0] == pytest.approx(3.0) and observation[1] == pytest.approx(0.2)
    assert info["sim_time"] == pytest.approx(0.3)


def test_seeded_reset_restarts_sim_time_and_unseeded_does_not():
    backend = fake()
    env = make_env(backend)
    env.reset(seed=3)
    env.reset()
    assert backend.resets == [True, False]


# -- actions -------------------------------------------------------------------------------------

def wheel_commands(actions, **overrides):
    backend = fake()
    env = make_env(backend, **overrides)
    env.reset()
    for action in actions:
        env.step(action)
    return [value for controller, value in backend.commands if controller == WHEEL_CONTROLLER]


def test_fixed_actions():
    # The first command is init_roll_vel, sent by reset.
    assert wheel_commands([0, 1, 2]) == [0.0, 100.0, -100.0, 0.0]


def test_increments_start_from_the_previous_command_and_are_clipped():
    assert wheel_commands([3, 3, 4]) == [0.0, 10.0, 20.0, 10.0]
    assert wheel_commands([0, 3, 4, 4]) == [0.0, 100.0, 100.0, 90.0, 80.0]
    assert wheel_commands([1, 4, 3]) == [0.0, -100.0, -100.0, -90.0]
    assert wheel_commands([2, 4, 4]) == [0.0, 0.0, -10.0, -20.0]


def test_increment_after_reset_starts_from_init_roll_vel():
    assert wheel_commands([3], init_roll_vel=5.0) == [5.0, 15.0]
    assert wheel_commands([4], init_roll_vel=95.0, roll_speed_increment_value=10.0) == [95.0, 85.0]
    assert wheel_commands([3], init_roll_vel=95.0, roll_speed_increment_value=10.0) == [95.0, 100.0]


def test_numpy_integer_actions_are_accepted():
    assert wheel_commands([np.int64(1), np.int32(3)]) == [0.0, -100.0, -90.0]


def test_a_0d_integer_array_is_an_action_as_sb3s_predict_gives_it():
    """`action, _ = model.predict(obs); env.step(action)`: Discrete accepts a 0-d integer array, so does the env."""
    assert wheel_commands([np.array(1), np.array(3, dtype=np.int32)]) == [0.0, -100.0, -90.0]


# -- observation ---------------------------------------------------------------------------------

def test_observation_order_dtype_and_bounds():
    backend = fake(at_reset=readings(y=0.7, wheel=12.5, roll=0.3, pitch=-0.1, yaw=0.05, v_y=0.25),
                          script=[readings(stamp=0.06, y=0.9, wheel=-40.0, roll=-1.2, pitch=0.15, yaw=-0.07,
                                           v_y=-0.5)])
    env = make_env(backend, init_cube_pose=Point(x=0.0, y=0.5, z=0.0))
    observation, _ = env.reset()
    assert observation.dtype == np.float32 and observation.shape == (6,)
    assert env.observation_space.contains(observation)
    np.testing.assert_allclose(observation, [12.5, 0.2, 0.3, -0.1, 0.25, 0.05], atol=1e-6)
    observation, *_ = env.step(2)
    assert observation.dtype == np.float32
    assert env.observation_space.contains(observation)
    np.testing.assert_allclose(observation, [-40.0, 0.4, -1.2, 0.15, -0.5, -0.07], atol=1e-6)


def test_observation_stays_inside_the_space_at_the_extremes():
    backend = fake(at_reset=readings(wheel=5000.0, roll=math.pi, yaw=-math.pi, pitch=math.pi / 2 - 1e-9))
    env = make_env(backend, max_pitch_angle=10.0, max_yaw_angle=10.0)
    observation, _ = env.reset()
    assert observation[0] == 1000.0, "wheel speed is clipped to the URDF limit"
    assert env.observation_space.contains(observation), observation


# -- API misuse ----------------------------------------------------------------------------------

def test_step_before_reset_raises():
    env = make_env(fake())
    with pytest.raises(gymnasium.error.ResetNeeded):
        env.step(0)


@pytest.mark.parametrize("action", [5, -1, 2.5, "0", np.array(5), np.array([1]), np.array(1.0), np.array(True)])
def test_action_outside_the_space_raises_value_error(action):
    backend = fake()
    env = make_env(backend)
    env.reset()
    with pytest.raises(ValueError):
        env.step(action)
    assert backend.steps == [], "an invalid action must not advance the sim"


def test_registered_env_uses_this_class_with_the_yaml_nsteps_as_its_time_limit():
    spec = gymnasium.spec(ONE_DISK_WALK.env_id)
    assert spec.entry_point == "moving_cube_training.envs.one_disk_walk:MovingCubeOneDiskWalkEnv"
    assert spec.max_episode_steps == ONE_DISK_WALK.max_episode_steps == ONE_DISK_WALK.default_params().nsteps


def test_unknown_backend_name_raises():
    with pytest.raises(ValueError, match="backend"):
        MovingCubeOneDiskWalkEnv(backend="gazebo", params=params())


def test_params_of_another_task_are_refused():
    with pytest.raises(TypeError, match="CubeParams"):
        MovingCubeOneDiskWalkEnv(backend=fake(), params=object())


# -- CubeStateKey --------------------------------------------------------------------------------

def obs(wheel=0.0, y=0.0, roll=0.0, pitch=0.0, v_y=0.0, yaw=0.0):
    return np.array([wheel, y, roll, pitch, v_y, yaw], dtype=np.float32)


@pytest.fixture
def key():
    return CubeStateKey(ONE_DISK_WALK.default_params())


def test_cube_at_rest(key):
    assert key.key(obs()) == "11_2_2_2"


def test_negative_zero_is_zero(key):
    assert key.key(obs(wheel=-0.0, roll=-0.0, v_y=-0.0, yaw=-0.0)) == key.key(obs())


def test_a_cube_one_roll_later_looks_the_same(key):
    assert key.key(obs(roll=-math.pi / 2)) == key.key(obs(roll=0.0))
    assert key.key(obs(roll=math.pi / 2)) == key.key(obs(roll=0.0))
    assert key.key(obs(roll=-math.pi / 2 + 0.15)) == key.key(obs(roll=0.15))


def test_a_rocking_cube_is_not_a_flat_one(key):
    assert key.key(obs(roll=0.15)) != key.key(obs(roll=0.0))
    assert key.key(obs(roll=-0.15)) != key.key(obs(roll=0.0))
    assert key.key(obs(roll=0.15)) != key.key(obs(roll=-0.15))


def test_wheel_speeds_the_actions_reach_are_distinct_states(key):
    speeds = np.arange(-100.0, 101.0, 10.0)
    keys = [key.key(obs(wheel=s)) for s in speeds]
    assert len(set(keys)) == len(speeds)


def test_resting_moving_and_turned_are_distinct(key):
    assert key.key(obs(v_y=0.01)) == key.key(obs())
    assert key.key(obs(v_y=0.1)) != key.key(obs())
    assert key.key(obs(v_y=-0.1)) != key.key(obs(v_y=0.1))
    assert key.key(obs(yaw=0.01)) == key.key(obs())
    assert key.key(obs(yaw=0.05)) != key.key(obs())


def test_unused_dimensions_do_not_change_the_key(key):
    assert key.key(obs(y=3.0, pitch=0.1)) == key.key(obs())


@pytest.mark.parametrize("dimension", [0, 2, 4, 5], ids=["wheel", "roll", "y_speed", "yaw"])
def test_nan_raises(key, dimension):
    observation = obs()
    observation[dimension] = np.nan
    with pytest.raises(ValueError):
        key.key(observation)


# -- params --------------------------------------------------------------------------------------

def test_default_params_load_typed_from_the_task_yaml():
    p = ONE_DISK_WALK.default_params()
    assert isinstance(p, CubeParams)
    assert (p.alpha, p.nsteps, p.n_actions, p.running_step) == (0.1, 1000, 5, 0.06)
    assert isinstance(p.end_episode_points, float) and isinstance(p.nepisodes, int)
    assert p.init_cube_pose == Point(x=0.0, y=0.0, z=0.0)
    assert ONE_DISK_WALK.config_path.parent.parent.name == "moving_cube_training"


def test_rosparam_form_validates_like_the_file_and_round_trips():
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    p = CubeParams.from_mapping(document["moving_cube"], "rosparam")
    assert p == ONE_DISK_WALK.default_params()
    assert CubeParams.from_mapping(p.to_mapping(), "params.yaml") == p


def bad(**changes):
    values = ONE_DISK_WALK.default_params().to_mapping()
    for k, v in changes.items():
        if v is None:
            del values[k]
        else:
            values[k] = v
    return values


@pytest.mark.parametrize("values, name", [
    (bad(alpha=None), "alpha"),
    (bad(alpha=1.5), "alpha"),
    (bad(gamma=-0.1), "gamma"),
    (bad(epsilon="high"), "epsilon"),
    (bad(nepisodes=0), "nepisodes"),
    (bad(nsteps=0), "nsteps"),
    (bad(epsilon_discount=2), "epsilon_discount"),
    (bad(n_actions=3), "n_actions"),
    (bad(init_cube_pose={"x": 0.0, "y": 0.0}), "init_cube_pose/z"),
    (bad(init_cube_pose=0.0), "init_cube_pose"),
], ids=["missing_alpha", "alpha_1.5", "gamma_negative", "epsilon_str", "nepisodes_0", "nsteps_0",
        "epsilon_discount_2", "n_actions_3", "pose_without_z", "pose_not_a_mapping"])
def test_bad_params_give_one_line_naming_key_and_source(values, name):
    with pytest.raises(ParamError) as info:
        CubeParams.from_mapping(values, "file.yaml")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("file.yaml: ")
    assert f"'{name}'" in message


def test_the_robot_resources_resolve_through_ros_package_paths():
    assert MOVING_CUBE.urdf_path.is_file() and MOVING_CUBE.urdf_path.parent.parent.name == "moving_cube_description"
    assert MOVING_CUBE.sim_config_path.is_file()
