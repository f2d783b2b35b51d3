"""Unit tests for the monoped's tasks (no ROS master): Monoped-v0's reward terms, termination, observation,
state key and actions on hand-made readings, the params, and both tasks on the direct backend."""
import dataclasses
import math
import xml.etree.ElementTree as ElementTree

import gymnasium
import numpy as np
import pytest
from tf.transformations import euler_from_quaternion, quaternion_from_euler

from hopper_training.envs.hop import HOP, HopParams, MonopedHopEnv
from hopper_training.envs.stay_up import STAY_UP, MonopedEnv
from hopper_training.params import MonopedParams
from hopper_training.robot import CONTROLLERS, JOINTS, MONOPED
from hopper_training.state import TiltStateKey, TutorialStateKey, monoped_state_key
from pybullet_sim.readings import ContactPoint, ContactReading, ImuReading, JointStateReading, OdometryReading
from robot_rl import DirectBackend, ParamError, Point, Readings

from fake_backend import FakeBackend

# config/stay_up.yaml (the tutorial's qlearn_params.yaml)
ALIVE, DONE, DESIRED_FORCE = 100.0, -1000.0, 7.08


def foot_contact(force=(0.0, 0.0, 7.08)):
    return ContactPoint("monoped::lowerleg_contactsensor_link::lowerleg_contactsensor_link_collision",
                        "ground_plane::link::collision", force, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                        (0.0, 0.0, 1.0), 0.001)


def readings(position=(0.0, 0.0, 1.0), rpy=(0.0, 0.0, 0.0), joints=(0.0, 0.0, 0.0), effort=(0.0, 0.0, 0.0),
             total_force=(0.0, 0.0, 0.0), contacts=None, odom_rpy=(0.0, 0.0, 0.0), stamp=0.0, names=JOINTS,
             rates=(0.0, 0.0, 0.0)):
    """Hand-made Readings as the sim publishes them; `contacts` None = one contact iff total_force != 0."""
    if contacts is None:
        contacts = (foot_contact(total_force),) if any(total_force) else ()
    order = [JOINTS.index(name) for name in names]
    return Readings(
        JointStateReading(stamp, tuple(names), tuple(joints[i] for i in order), (0.0, 0.0, 0.0),
                          tuple(effort[i] for i in order)),
        {"p3d_base_controller": OdometryReading(stamp, "world", "base", tuple(position),
                                                tuple(quaternion_from_euler(*odom_rpy)), (0.0,) * 3, (0.0,) * 3),
         "gazebo_ros_imu_controller": ImuReading(stamp, "base", tuple(quaternion_from_euler(*rpy)),
                                                 tuple(rates), (0.0, 0.0, 9.81)),
         "lowerleg_contactsensor_sensor": ContactReading(stamp, "lowerleg_contactsensor_link", tuple(contacts),
                                                         tuple(total_force), (0.0, 0.0, 0.0))})


def params(task=STAY_UP, **overrides):
    """The task's YAML params in the tutorial's action mode (the tutorial's rule: test_monoped_actions.py
    covers the others), with `overrides`."""
    return dataclasses.replace(task.default_params(), **{"action_mode": "tutorial", **overrides})


def env_on(r, env_class=MonopedEnv, **overrides):
    """An env whose robot always reads `r`, reset."""
    env = env_class(backend=FakeBackend(r), params=params(env_class.task, **overrides))
    env.reset()
    return env


def step_on(r, action=0, **overrides):
    """(reward, terminated, info) of one step of an env whose robot always reads `r`."""
    _, reward, terminated, _, info = env_on(r, **overrides).step(action)
    return reward, terminated, info


def terms(info):
    return {key[len("reward_"):]: value for key, value in info.items() if key.startswith("reward_")}


# -- rewards --------------------------------------------------------------------------------------
# A leaning, displaced robot with bent joints, efforts and a 5 N contact.
LEANING = dict(position=(0.3, 0.4, 1.0), rpy=(0.1, -0.2, 0.3), joints=(0.1, -0.2, -0.3),
               effort=(1.0, -2.0, 3.0), total_force=(3.0, 4.0, 0.0), rates=(0.05, -0.5, 0.7))


def test_each_reward_term_with_the_yaml_weights():
    reward, terminated, info = step_on(readings(**LEANING))
    assert not terminated
    assert terms(info) == pytest.approx({
        "alive": ALIVE,
        "joint_position": -(0.1 + 0.2 + 0.3),        # w1 = 1
        "joint_effort": 0.0,                         # w2 = 0
        "contact_force": -abs(5.0 - 7.08),           # w3 = 1
        "orientation": -(0.1 + 0.2 + 0.3),           # w4 = 1
        "distance": -0.5})                           # w5 = 1, to (0, 0, 1)
    assert reward == pytest.approx(ALIVE - (0.6 + 0.0 + 2.08 + 0.6 + 0.5))


def test_effort_term_counts_with_weight_r2_one():
    reward, _, info = step_on(readings(**LEANING), weight_r2=1.0)
    assert info["reward_joint_effort"] == pytest.approx(-(1.0 + 2.0 + 3.0))
    assert reward == pytest.approx(ALIVE - (0.6 + 6.0 + 2.08 + 0.6 + 0.5))


def test_weights_multiply_their_own_term():
    reward, _, info = step_on(readings(**LEANING), weight_r1=2.0, weight_r2=0.5, weight_r3=3.0, weight_r4=4.0,
                              weight_r5=5.0, alive_reward=10.0)
    expected = {"alive": 10.0, "joint_position": -2.0 * 0.6, "joint_effort": -0.5 * 6.0,
                "contact_force": -3.0 * 2.08, "orientation": -4.0 * 0.6, "distance": -5.0 * 0.5}
    assert terms(info) == pytest.approx(expected)
    assert reward == pytest.approx(sum(expected.values()))


def test_orientation_term_uses_desired_yaw_and_absolute_values():
    _, _, info = step_on(readings(rpy=(-0.1, 0.2, 0.3)), desired_yaw=0.5)
    assert info["reward_orientation"] == pytest.approx(-(0.1 + 0.2 + abs(0.3 - 0.5)))


def test_orientation_comes_from_the_imu_not_the_odometry():
    env = env_on(readings(rpy=(0.1, 0.0, 0.0), odom_rpy=(0.0, 0.5, 0.0)))
    observation, *_ = env.step(0)
    assert observation[1:4] == pytest.approx((0.1, 0.0, 0.0), abs=1e-6)


def test_distance_to_a_moved_desired_point():
    _, _, info = step_on(readings(position=(1.0, 2.0, 2.0)), desired_pose=Point(x=1.0, y=-1.0, z=6.0))
    assert info["reward_distance"] == pytest.approx(-5.0)


def test_upright_robot_at_the_desired_point_in_the_air():
    """Only the contact term remains: no contact means force 0, |0 - desired_force|."""
    reward, terminated, _ = step_on(readings())
    assert (reward, terminated) == (pytest.approx(ALIVE - DESIRED_FORCE), False)


def test_contact_force_is_zero_without_contacts_even_if_total_force_is_not():
    env = env_on(readings(total_force=(1.0, 2.0, 3.0), contacts=()))
    observation, _, _, _, info = env.step(0)
    assert observation[4] == 0.0 and info["reward_contact_force"] == pytest.approx(-DESIRED_FORCE)
    observation, *_ = env_on(readings(total_force=(1.0, 2.0, 2.0))).step(0)
    assert observation[4] == pytest.approx(3.0)


def test_contact_force_is_the_magnitude_of_total_force_in_any_direction():
    """The sim reports total_wrench in the foot's frame (its x points down): only |F| counts."""
    _, _, info = step_on(readings(total_force=(-7.08, 0.0, 0.0)))
    assert info["reward_contact_force"] == pytest.approx(0.0)


# -- done -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("height, done", [
    (0.4999, True), (0.5, False), (0.5001, False),   # min_height 0.5 is inside
    (2.9999, False), (3.0, True), (3.5, True),       # max_height 3.0 is outside
    (-0.2, True),
])
def test_height_limits(height, done):
    reward, terminated, info = step_on(readings(position=(0.0, 0.0, height)))
    assert terminated is done and info["fell"] is done and info["base_height"] == height
    if done:
        assert reward == DONE and terms(info) == {"fall": DONE}
    else:
        assert reward > DONE and "reward_fall" not in info


@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_inclination_limit_is_exclusive(axis, sign):
    """|roll| or |pitch| equal to max_incl is a fall; just below it is not."""
    rpy = [0.0, 0.0, 0.0]
    rpy[axis] = sign * 1.5
    r = readings(rpy=rpy)
    angle = abs(euler_from_quaternion(r.sensors["gazebo_ros_imu_controller"].orientation)[axis])
    assert step_on(r, max_incl=angle)[:2] == (DONE, True)
    reward, terminated, _ = step_on(r, max_incl=float(np.nextafter(angle, math.inf)))
    assert not terminated and reward > DONE


@pytest.mark.parametrize("rpy, done", [
    ((1.56, 0.0, 0.0), False), ((1.58, 0.0, 0.0), True), ((-1.58, 0.0, 0.0), True),
    ((0.0, 1.56, 0.0), False), ((0.0, -1.56, 0.0), False), ((0.0, 1.5705, 0.0), True),
    ((0.0, 0.0, 3.0), False),  # yaw never ends an episode
])
def test_inclination_with_the_yaml_max_incl(rpy, done):
    assert step_on(readings(rpy=rpy))[1] is done


# -- observations and the tutorial's state key ----------------------------------------------------
def test_observations_in_the_tutorial_order_then_the_tilt_rates():
    observation, *_ = env_on(readings(**LEANING)).step(0)
    assert observation.dtype == np.float32 and observation.shape == (10,)
    # distance, roll, pitch, yaw, contact force, haa, hfe, kfe, roll rate, pitch rate
    assert observation.tolist() == pytest.approx([0.5, 0.1, -0.2, 0.3, 5.0, 0.1, -0.2, -0.3, 0.05, -0.5], abs=1e-6)


def tutorial_key(obs, **overrides):
    return TutorialStateKey(params(**overrides)).key(np.array(obs, dtype=float))


def tilt_key(roll=0.0, pitch=0.0, roll_rate=0.0, pitch_rate=0.0, force=0.0, kfe=0.0):
    observation = np.array([0.0, roll, pitch, 0.0, force, 0.0, 0.0, kfe, roll_rate, pitch_rate], dtype=np.float32)
    return TiltStateKey(params()).key(observation)


def test_tilt_key_tells_forward_from_backward():
    assert tilt_key(pitch=0.01) != tilt_key(pitch=-0.01)
    assert tilt_key(pitch=0.01, pitch_rate=0.1) != tilt_key(pitch=-0.01, pitch_rate=0.1)


def test_tilt_key_bins_tilt_and_rate_by_decades_and_sees_knee_and_contact():
    # sign of pitch, tilt decade (edges 1e-6 .. 0.1), rate decade (edges 1e-6 .. 1), knee, contact
    assert tilt_key() == "1_0_0_2_0"
    assert tilt_key(roll=3e-4, pitch=-2e-5) == "0_3_0_2_0"          # the larger of abs(roll), abs(pitch)
    assert tilt_key(roll_rate=-0.02, pitch_rate=0.5) == "1_0_6_2_0"  # the larger of the abs rates
    assert tilt_key(kfe=-0.1) == "1_0_0_1_0" and tilt_key(kfe=-0.5) == "1_0_0_0_0"
    assert tilt_key(force=7.0) == "1_0_0_2_1"


def test_tilt_key_puts_values_beyond_the_bins_in_the_edge_bins():
    assert tilt_key(pitch=1.2, pitch_rate=40.0) == tilt_key(pitch=0.3, pitch_rate=2.0) == "1_6_7_2_0"
    assert tilt_key(pitch=1e-12, pitch_rate=-1e-12) == tilt_key(pitch=2e-9) == "1_0_0_2_0"


def test_the_params_choose_the_key():
    assert isinstance(monoped_state_key(params()), TiltStateKey)
    assert isinstance(monoped_state_key(params(state_key="tutorial")), TutorialStateKey)


def test_state_key_of_the_upright_robot_at_rest_in_the_air():
    """The tutorial's "5.05.05.05.01.05.05.010.0": force 0 sits on the first edge (bin 1), kfe 0 on
    the last (bin 10)."""
    observation, _ = MonopedEnv(backend=FakeBackend(readings()), params=params()).reset()
    assert tutorial_key(observation) == "5_5_5_5_1_5_5_10"


# Edges numpy.linspace(min, max, 10) with the ranges of original_interfaces.md B3:
#   distance [-2.5, 2.5] step 0.5556; roll, pitch [-1.57, 1.57] step 0.3489; yaw [-2pi, 2pi] step 1.3963;
#   force [0, 14.16] step 1.5733; haa, hfe [-1.6, 1.6] step 0.3556; kfe [-1.6, 0] step 0.1778.
@pytest.mark.parametrize("obs, key", [
    # distance 2.6 > 2.5 -> 10; roll -1.6 < -1.57 -> 0; pitch on the last edge -> 10; yaw 0.7 >= 0.698 -> 6;
    # force 7.08 in [6.29, 7.87) -> 5; haa -1.59 in [-1.6, -1.244) -> 1; hfe 1.6 -> 10;
    # kfe -0.8 in [-0.889, -0.711) -> 5
    ([2.6, -1.6, 1.57, 0.7, 7.08, -1.59, 1.6, -0.8], "10_0_10_6_5_1_10_5"),
    # distance 0.3 in [0.278, 0.833) -> 6; roll 0.2 in [0.174, 0.523) -> 6; pitch -0.2 in [-0.523, -0.174) -> 4;
    # yaw -0.7 in [-2.094, -0.698) -> 4; force 15 > 14.16 -> 10; haa 0.5 in [0.178, 0.533) -> 6;
    # hfe -0.5 in [-0.533, -0.178) -> 4; kfe -1.7 < -1.6 -> 0
    ([0.3, 0.2, -0.2, -0.7, 15.0, 0.5, -0.5, -1.7], "6_6_4_4_10_6_4_0"),
    # everything on its first edge -> 1 each (digitize: edges[i-1] <= x < edges[i])
    ([-2.5, -1.57, -1.57, -2 * math.pi, 0.0, -1.6, -1.6, -1.6], "1_1_1_1_1_1_1_1"),
])
def test_state_key_hand_computed(obs, key):
    assert tutorial_key(obs) == key


def test_state_key_bins_come_from_the_params():
    """max_height - min_height, max_incl and desired_force set the bin ranges."""
    # distance 0.95 in [-1, 1]: edges step 2/9, 0.95 >= 0.778 -> 9; roll 0.9 >= 0.778 -> 9;
    # pitch -0.95 in [-1, -0.778) -> 1; force 19.9 in [17.78, 20) -> 9
    assert tutorial_key([0.95, 0.9, -0.95, 0.0, 19.9, 0.0, 0.0, 0.0], max_height=2.0, min_height=1.0, max_incl=1.0,
                        desired_force=10.0) == "9_9_1_5_9_5_5_10"


# -- actions --------------------------------------------------------------------------------------
def targets(joints, action, names=JOINTS):
    backend = FakeBackend(readings(joints=joints, names=names))
    env = MonopedEnv(backend=backend, params=params())
    env.reset()
    backend.commands.clear()
    env.step(action)
    assert [controller for controller, _ in backend.commands] == list(CONTROLLERS)
    return [value for _, value in backend.commands]


@pytest.mark.parametrize("action, expected", [
    (0, [0.15, -0.2, -0.3]), (1, [0.05, -0.2, -0.3]),
    (2, [0.1, -0.15, -0.3]), (3, [0.1, -0.25, -0.3]),
    (4, [0.1, -0.2, -0.25]), (5, [0.1, -0.2, -0.35]),
])
def test_each_action_moves_one_joint_by_the_increment(action, expected):
    assert targets((0.1, -0.2, -0.3), action) == pytest.approx(expected)


@pytest.mark.parametrize("joints, action, expected", [
    ((0.0, 0.0, 0.0), 4, [0.0, 0.0, 0.0]),        # kfe's upper limit is 0.0
    ((0.0, 0.0, -0.02), 4, [0.0, 0.0, 0.0]),
    ((1.58, 0.0, 0.0), 0, [1.6, 0.0, 0.0]),
    ((-1.58, 0.0, 0.0), 1, [-1.6, 0.0, 0.0]),
    ((0.0, 1.59, 0.0), 2, [0.0, 1.6, 0.0]),
    ((0.0, -1.59, 0.0), 3, [0.0, -1.6, 0.0]),
    ((0.0, 0.0, -1.59), 5, [0.0, 0.0, -1.6]),
    ((1.6, 0.0, 0.0), 1, [1.55, 0.0, 0.0]),       # moving back from a limit is not clamped
])
def test_actions_are_clamped_to_the_urdf_limits(joints, action, expected):
    assert targets(joints, action) == pytest.approx(expected)


def test_joint_limits_are_the_urdfs():
    joints = {j.get("name"): j.find("limit") for j in ElementTree.parse(MONOPED.urdf_path).getroot().findall("joint")}
    assert [(float(joints[name].get("lower")), float(joints[name].get("upper"))) for name in JOINTS] == \
        list(MonopedEnv(backend=FakeBackend(readings()), params=params()).joint_limits) == \
        [(-1.6, 1.6), (-1.6, 1.6), (-1.6, 0.0)]


def test_joint_positions_are_read_by_name_not_by_index():
    assert targets((0.1, -0.2, -0.3), 0, names=("kfe_joint", "haa_joint", "hfe_joint")) == \
        pytest.approx([0.15, -0.2, -0.3])


def test_reset_commands_every_joint_to_zero_and_a_step_is_one_physics_step():
    backend = FakeBackend(readings(joints=(1.58, -0.2, -0.3)))
    env = MonopedEnv(backend=backend, params=params())
    env.reset(seed=3)
    assert backend.resets == [True]
    assert backend.commands == list(zip(CONTROLLERS, (0.0, 0.0, 0.0)))
    env.step(0)
    assert backend.steps == [20]  # running_step 0.02 s of 1 ms physics steps
    env.reset()
    assert backend.resets == [True, False]  # an unseeded reset is reset_world


# -- params ---------------------------------------------------------------------------------------
SOURCE = "/tmp/stay_up.yaml"


def yaml_params():
    return STAY_UP.default_params().to_mapping()


def param_error(values):
    with pytest.raises(ParamError) as info:
        MonopedParams.from_mapping(values, SOURCE)
    message = str(info.value)
    assert message.startswith(f"{SOURCE}: ") and "\n" not in message
    return message


def test_the_yaml_is_valid_and_keeps_the_tutorial_values():
    p = STAY_UP.default_params()
    assert (p.epsilon, p.joint_increment_value, p.alive_reward, p.done_reward) == (0.9, 0.05, 100.0, -1000.0)
    assert (p.max_height, p.min_height, p.max_incl, p.desired_force) == (3.0, 0.5, 1.57, 7.08)
    assert p.desired_pose == Point(x=0.0, y=0.0, z=1.0)
    assert [p.weight_r1, p.weight_r2, p.weight_r3, p.weight_r4, p.weight_r5] == [1.0, 0.0, 1.0, 1.0, 1.0]


@pytest.mark.parametrize("key", ["alpha", "nsteps", "weight_r3", "running_step"])
def test_missing_key(key):
    values = yaml_params()
    del values[key]
    assert param_error(values) == f"{SOURCE}: missing parameter '{key}'"


def test_missing_nested_key():
    values = yaml_params()
    del values["desired_pose"]["z"]
    assert param_error(values) == f"{SOURCE}: missing parameter 'desired_pose/z'"


@pytest.mark.parametrize("key, value", [("alpha", 2), ("nsteps", 0), ("max_incl", 0.0), ("running_step", -0.001),
                                        ("desired_force", 0.0)])
def test_out_of_range(key, value):
    message = param_error({**yaml_params(), key: value})
    assert f"'{key}'" in message and "out of range" in message


def test_wrong_type():
    message = param_error({**yaml_params(), "nsteps": 100.5})
    assert "'nsteps'" in message and "expected int" in message


@pytest.mark.parametrize("min_height, max_height", [(3.0, 3.0), (3.5, 3.0)])
def test_min_height_must_be_below_max_height(min_height, max_height):
    message = param_error({**yaml_params(), "min_height": min_height, "max_height": max_height})
    assert "'min_height'" in message and "'max_height'" in message


# -- the hop task ---------------------------------------------------------------------------------
def test_hop_rewards_velocity_along_x_on_top_of_the_stay_up_terms():
    backend = FakeBackend(readings(position=(0.0, 0.0, 1.0)),
                          script=[readings(position=(0.01, 0.0, 1.0)), readings(position=(0.005, 0.0, 1.0))])
    env = MonopedHopEnv(backend=backend, params=params(HOP, running_step=0.02, target_speed=10.0))
    env.reset()
    _, reward, _, _, info = env.step(0)
    weight = env.params.forward_reward_weight
    assert info["reward_forward"] == pytest.approx(weight * 0.01 / 0.02)
    assert info["x_travelled"] == pytest.approx(0.01)
    assert "reward_alive" in info and "reward_distance" in info
    _, _, _, _, info = env.step(0)
    assert info["reward_forward"] == pytest.approx(-weight * 0.005 / 0.02)
    assert info["x_travelled"] == pytest.approx(0.005)


def test_hop_forward_reward_counts_the_velocity_up_to_the_target_speed():
    backend = FakeBackend(readings(position=(0.0, 0.0, 1.0)),
                          script=[readings(position=(0.02, 0.0, 1.0)), readings(position=(0.0, 0.0, 1.0))])
    env = MonopedHopEnv(backend=backend, params=params(HOP, running_step=0.02, target_speed=0.4))
    env.reset()
    weight = env.params.forward_reward_weight
    assert env.step(0)[4]["reward_forward"] == pytest.approx(weight * 0.4)   # 1 m/s, capped
    assert env.step(0)[4]["reward_forward"] == pytest.approx(-weight * 1.0)  # backwards in full


def test_the_hop_yaml_follows_hopper_v5():
    p = HOP.default_params()
    assert p.forward_reward_weight == p.alive_reward  # per m/s, as Hopper-v5's 1 against 1
    assert p.target_speed == 0.4 and p.max_incl == 0.5
    assert p.q_init == pytest.approx((p.alive_reward + p.forward_reward_weight * p.target_speed) / (1 - p.gamma))


def test_hop_params_add_the_forward_weight():
    p = HOP.default_params()
    assert isinstance(p, HopParams) and p.forward_reward_weight > 0.0 and p.weight_r5 == 0.0
    values = p.to_mapping()
    del values["forward_reward_weight"]
    with pytest.raises(ParamError, match="forward_reward_weight"):
        HopParams.from_mapping(values, "hop.yaml")


# -- the env on the direct backend ----------------------------------------------------------------
def test_direct_observations_are_float32_in_the_space_in_the_tutorial_order():
    """At the tutorial's 1 ms steps: 200 steps of these actions keep the monoped up."""
    env = gymnasium.make(STAY_UP.env_id, backend="direct", params=params(running_step=0.001)).unwrapped
    try:
        observation, _ = env.reset(seed=0)
        actions = [3, 3, 5, 5, 0, 2, 4, 1] * 25
        touched = False
        for action in [None] + actions:
            if action is not None:
                observation, reward, terminated, truncated, _ = env.step(action)
                assert not terminated
            assert observation.dtype == np.float32 and env.observation_space.contains(observation)
            r = env.readings
            odom = r.sensors["p3d_base_controller"]
            contact = r.sensors["lowerleg_contactsensor_sensor"]
            force = float(np.linalg.norm(contact.total_force)) if contact.contacts else 0.0
            touched = touched or force > 0.0
            imu = r.sensors["gazebo_ros_imu_controller"]
            expected = [math.dist(odom.position, (0.0, 0.0, 1.0)), *euler_from_quaternion(imu.orientation),
                        force, *r.joints.position, *imu.angular_velocity[:2]]
            assert observation.tolist() == pytest.approx(expected, abs=1e-5)
        assert touched, "the foot should reach the ground (spawned 5 cm above it) within 0.2 s"
    finally:
        env.close()


def test_same_seed_same_episode_on_the_direct_backend():
    def episode():
        env = gymnasium.make(STAY_UP.env_id, backend="direct", seed=4, params=params()).unwrapped
        try:
            env.reset(seed=4)
            steps = [env.step(a) for a in [2, 2, 4, 5, 0, 1] * 10]
            return [(observation.tolist(), reward) for observation, reward, *_ in steps]
        finally:
            env.close()
    first = episode()
    assert first == episode()
    assert len({round(float(r), 9) for _, r in first}) > 1


@pytest.mark.parametrize("restart_time", [True, False], ids=["reset_simulation", "reset_world"])
def test_contact_reading_is_empty_right_after_a_reset(restart_time):
    """The robot is back at its spawn pose, the foot 5 cm above the ground: no contact."""
    backend = DirectBackend(MONOPED.urdf_path, MONOPED.sim_config_path)
    try:
        landed = backend.step(500).sensors["lowerleg_contactsensor_sensor"]
        assert landed.contacts, "the foot should be on the ground after 0.5 s"
        r = backend.reset(restart_time=restart_time)
        assert r.sensors["p3d_base_controller"].position[2] == pytest.approx(1.0, abs=0.05)
        contact = r.sensors["lowerleg_contactsensor_sensor"]
        assert (contact.contacts, contact.total_force) == ((), (0.0, 0.0, 0.0))
    finally:
        backend.close()


def test_a_seeded_reset_after_an_episode_gives_the_first_observation_of_a_fresh_env():
    env = gymnasium.make(STAY_UP.env_id, backend="direct", params=params()).unwrapped
    try:
        fresh, _ = env.reset(seed=0)
        assert tutorial_key(fresh) == "5_5_5_5_1_5_5_10"
        for _ in range(300):
            env.step(2)
        again, _ = env.reset(seed=0)
        assert again.tolist() == fresh.tolist()
    finally:
        env.close()
