"""Unit tests of the hopping controller (hopper_training.controller): its phase machine on hand-made readings,
its foot-placement law, its leg model against PyBullet's, and short hops in an in-process World (no ROS)."""
import json
import math

import numpy as np
import pybullet as p
import pytest

from hopper_training import TASKS
from hopper_training.controller.core import (
    HopController,
    HopGains,
    HopInput,
    LegModel,
    Phase,
    foot_placement,
    hips_for_foot,
    level_rotation,
)
from hopper_training.controller.policy import FIVE_MS_GAIN_CHANGES, ControllerPolicy, controller_params
from hopper_training.controller.trials import lean, load_sim_config, make_world, run_trial
from hopper_training.envs.end_to_end import END_TO_END
from hopper_training.robot import MONOPED
from pybullet_sim.config import parse_robot_config
from pybullet_sim.errors import ConfigError
from robot_rl import Episode, ScriptedPolicy, aggregate, evaluation, make_env
from robot_rl.evaluation import with_push

UPRIGHT = (0.0, 0.0, 0.0, 1.0)


def reading(time, contact, knee=-0.6, knee_rate=0.0, z=0.9, vz=0.0, vx=0.0, hips=(0.0, 0.3)):
    return HopInput(time=time, joint_position=(hips[0], hips[1], knee), joint_velocity=(0.0, 0.0, knee_rate),
                    orientation=UPRIGHT, angular_velocity=(0.0, 0.0, 0.0), position=(0.0, 0.0, z),
                    linear_velocity=(vx, 0.0, vz), contact=contact)


def test_a_hop_goes_flight_loading_compression_thrust_unloading_flight():
    gains = HopGains()
    controller = HopController(gains)
    assert controller.phase is Phase.FLIGHT
    assert controller.update(reading(0.000, False))[2] == pytest.approx(gains.landing_knee)
    controller.update(reading(0.100, True, knee=-0.6, knee_rate=0.0))
    assert controller.phase is Phase.LOADING and controller.hops == 1
    targets = controller.update(reading(0.101, True, knee=-0.62, knee_rate=-2.0))
    assert controller.phase is Phase.COMPRESSION
    assert targets[2] == pytest.approx(gains.landing_knee), "the knee springs about the landing crouch"
    controller.update(reading(0.150, True, knee=-1.1, knee_rate=-0.5))
    assert controller.phase is Phase.COMPRESSION
    targets = controller.update(reading(0.160, True, knee=-1.15, knee_rate=0.1))
    assert controller.phase is Phase.THRUST
    assert targets[2] == pytest.approx(gains.thrust_knee), "the bottom of stance starts the thrust"
    controller.update(reading(0.200, True, knee=gains.thrust_knee - gains.unload_margin / 2, knee_rate=5.0))
    assert controller.phase is Phase.UNLOADING
    controller.update(reading(0.210, False))
    assert controller.phase is Phase.UNLOADING, "one reading without contact is not a lift-off yet"
    targets = controller.update(reading(0.210 + gains.lift_off_s, False))
    assert controller.phase is Phase.FLIGHT
    assert controller.stance_time == pytest.approx(0.110 + gains.lift_off_s)
    assert targets[2] == pytest.approx(gains.landing_knee), "in flight the knee crouches for the landing"
    controller.reset()
    assert (controller.phase, controller.hops) == (Phase.FLIGHT, 0)


def test_a_contact_that_comes_back_keeps_the_stance():
    controller = HopController()
    controller.update(reading(0.0, True))
    controller.update(reading(0.001, False))
    controller.update(reading(0.002, True))
    controller.update(reading(0.010, False))
    assert controller.phase is not Phase.FLIGHT


def test_the_thrust_adapts_to_the_apex():
    gains = HopGains(apex_target=1.0, thrust_gain=1.0, thrust_knee=-0.2)
    low = HopController(gains)
    for t in np.arange(0.0, 0.1, 0.001):  # a flight that peaks at 0.95 m (z + vz^2 / 2g constant)
        low.update(reading(t, False, z=0.95 - 0.5 * 9.81 * t * t, vz=-9.81 * t))
    low.update(reading(0.1, True))
    assert low.apex == pytest.approx(0.95, abs=1e-6)
    assert low.thrust_knee == pytest.approx(gains.thrust_knee + 0.05), "too low: a stronger thrust (knee straighter)"


def test_each_hop_adds_its_speed_error_to_the_placement():
    gains = HopGains(speed=(0.4, 0.0), placement_ki=0.03, max_placement_bias=0.06)
    controller = HopController(gains)
    for hop in range(3):
        for t in np.arange(0.0, 0.1, 0.001):
            controller.update(reading(hop + t, False, vx=0.2))
        controller.update(reading(hop + 0.1, True))
        controller.update(reading(hop + 0.2, False, vx=0.2))
        controller.update(reading(hop + 0.21, False, vx=0.2))
        assert controller.placement_bias[0] == pytest.approx(-0.006 * (hop + 1)), "behind, to speed up"
        assert controller.placement_bias[1] == pytest.approx(0.0)
    for hop in range(3, 40):
        controller.update(reading(hop, False, vx=0.2))
        controller.update(reading(hop + 0.1, True))
        controller.update(reading(hop + 0.2, False, vx=0.2))
        controller.update(reading(hop + 0.21, False, vx=0.2))
    assert controller.placement_bias[0] == pytest.approx(-0.06), "bounded"


def test_foot_placement_is_the_neutral_point_plus_the_speed_error():
    assert foot_placement(0.0, 0.0, 0.12, 0.2, 0.25) == 0.0
    assert foot_placement(0.5, 0.5, 0.12, 0.2, 0.25) == pytest.approx(0.5 * 0.12 / 2)
    assert foot_placement(0.0, 0.4, 0.12, 0.2, 0.25) == pytest.approx(-0.08), "behind, to speed up"
    assert foot_placement(0.4, 0.0, 0.12, 0.2, 0.25) == pytest.approx(0.024 + 0.08), "ahead, to slow down"
    assert foot_placement(10.0, 0.0, 0.12, 0.2, 0.25) == 0.25


@pytest.mark.parametrize("roll, pitch", [(0.0, 0.0), (0.1, -0.2), (-0.15, 0.1)])
@pytest.mark.parametrize("target", [(0.0, 0.0), (0.05, -0.03), (-0.08, 0.04)])
def test_the_hips_put_the_foot_where_placement_asks_whatever_the_tilt(roll, pitch, target):
    model, rotation = LegModel(), level_rotation(roll, pitch)
    haa, hfe = hips_for_foot(model, target, (0.0, 0.3, -0.6), rotation, iterations=6)
    foot = rotation @ model.foot_from_com((haa, hfe, -0.6))
    assert foot[:2] == pytest.approx(target, abs=1e-4)
    assert foot[2] < -0.5, "the foot stays below the centre of mass"


def test_in_flight_moving_forward_puts_the_foot_ahead():
    gains = HopGains(stance_time=0.1, placement_kv=0.2, flight_swing_gain=1.0)
    controller = HopController(gains)  # no hop yet: no per-hop bias
    haa, hfe, knee = controller.update(reading(0.0, False, vx=0.5, hips=(0.0, 0.3)))
    foot = LegModel().foot_from_com((haa, hfe, knee))
    assert foot[0] == pytest.approx(0.5 * 0.1 / 2 + 0.2 * 0.5, abs=2e-3) and abs(foot[1]) < 2e-3


def test_in_flight_the_hips_go_swing_gain_times_their_way_to_the_placement():
    """The body turns back by about 2/3 of a hip swing (leg/body inertia ~2): the hips overshoot to 3x."""
    ik = HopController(HopGains(flight_swing_gain=1.0)).update(reading(0.0, False, vx=0.3, hips=(0.02, 0.3)))
    swung = HopController(HopGains(flight_swing_gain=3.0)).update(reading(0.0, False, vx=0.3, hips=(0.02, 0.3)))
    assert swung[0] - 0.02 == pytest.approx(3.0 * (ik[0] - 0.02))
    assert swung[1] - 0.3 == pytest.approx(3.0 * (ik[1] - 0.3))


def test_standing_at_the_start_the_first_thrust_is_gentle():
    gains = HopGains()
    controller = HopController(gains)
    controller.update(reading(0.0, True, knee=-0.9, knee_rate=0.0))
    assert controller.phase is Phase.COMPRESSION, "standing is a stance under way"
    targets = controller.update(reading(0.001, True, knee=-0.9, knee_rate=0.0))
    assert controller.phase is Phase.THRUST, "the knee does not flex: thrust"
    assert targets[2] == pytest.approx(gains.start_thrust_knee)
    controller.update(reading(0.05, False))
    controller.update(reading(0.06, False))
    controller.update(reading(0.2, True))
    controller.update(reading(0.21, True, knee=-0.8, knee_rate=-1.0))
    assert controller.update(reading(0.25, True, knee=-1.0, knee_rate=0.5))[2] == pytest.approx(gains.thrust_knee)


def test_a_stance_torque_reaches_the_joint_through_its_position_pd():
    gains = HopGains(pid_p=10.0, pid_d=0.5)
    controller = HopController(gains)
    command = controller._target_for_torque(0.3, -2.0, 1.5)
    assert gains.pid_p * (command - 0.3) - gains.pid_d * -2.0 == pytest.approx(1.5)


def test_the_stance_hip_torques_aim_the_ground_force_at_the_centre_of_mass():
    model, controller = LegModel(), HopController(HopGains())
    q = (0.05, 0.5, -1.0)
    torques = controller._hip_torques_through_com(q, (0.0, 0.0, 0.0), -0.1, level_rotation(0.0, 0.0))
    foot, com = model.points(q)
    direction = (com - foot) / np.linalg.norm(com - foot)
    knee_torque = 10.0 * (-0.1 - q[2])
    per_newton = -model.jacobian(q).T @ direction
    force = knee_torque / per_newton[2]
    assert force > 0.0
    assert torques == pytest.approx(force * per_newton[:2])


def test_the_leg_model_is_the_urdfs():
    cid = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(MONOPED.urdf_path), useFixedBase=True, flags=p.URDF_USE_INERTIA_FROM_FILE,
                          physicsClientId=cid)
        model = LegModel()
        for q in [(0.0, 0.0, 0.0), (0.3, 0.5, -1.0), (-0.2, -0.3, -0.4)]:
            for index, value in enumerate(q):
                p.resetJointState(body, index, value, physicsClientId=cid)
            links = range(-1, p.getNumJoints(body, physicsClientId=cid))
            masses = [p.getDynamicsInfo(body, i, physicsClientId=cid)[0] for i in links]
            masses[0] = model.base_mass  # a fixed base reports mass 0
            positions = [p.getBasePositionAndOrientation(body, physicsClientId=cid)[0]] + [
                p.getLinkState(body, i, physicsClientId=cid)[0] for i in links if i >= 0]
            com = np.average(np.array(positions), axis=0, weights=masses)
            foot_link = p.getNumJoints(body, physicsClientId=cid) - 1
            foot = np.array(p.getLinkState(body, foot_link, physicsClientId=cid)[4])
            model_foot, model_com = model.points(q)
            assert model_foot == pytest.approx(foot, abs=1e-6)
            assert model_com == pytest.approx(com, abs=3e-4)  # the model leaves out the 0.1 g foot
    finally:
        p.disconnect(cid)


# -- in a World: the vertical slider and short hops --------------------------------------------------------
def test_base_constraint_must_be_known():
    params = load_sim_config(MONOPED.sim_config_path, base_constraint="sideways")
    with pytest.raises(ConfigError, match="base_constraint must be one of none, vertical"):
        parse_robot_config(params)
    assert parse_robot_config(load_sim_config(MONOPED.sim_config_path)).base_constraint == "none"


def test_on_the_vertical_slider_the_controller_hops_to_a_steady_height():
    world = make_world(MONOPED.urdf_path, load_sim_config(MONOPED.sim_config_path, base_constraint="vertical"))
    try:
        result = run_trial(world, HopController(), 3.0)
        end = world.model_state()
    finally:
        world.close()
    assert not result.fell and result.hops >= 6
    assert end.position[:2] == pytest.approx((0.0, 0.0), abs=1e-3), "the base slides along z only"
    assert result.max_tilt < 1e-3
    steady = result.apexes[2:]
    assert len(steady) >= 4 and max(steady) - min(steady) < 0.01 and min(steady) > 0.93


def test_free_the_controller_hops_from_a_lean_without_falling():
    world = make_world(MONOPED.urdf_path, load_sim_config(MONOPED.sim_config_path))
    try:
        lean(world, 0.04, 1.0)
        assert world.model_state().orientation == pytest.approx(
            (-math.sin(1.0) * math.sin(0.02), math.cos(1.0) * math.sin(0.02), 0.0, math.cos(0.02)), abs=1e-6)
        result = run_trial(world, HopController(), 3.0)
    finally:
        world.close()
    assert not result.fell and result.hops >= 6 and result.max_tilt < 0.5


def test_a_slow_control_period_loses_the_robot():
    """What the docs say the controller needs: a command every few ms (at the env's 20 ms it falls)."""
    world = make_world(MONOPED.urdf_path, load_sim_config(MONOPED.sim_config_path))
    try:
        lean(world, 0.04, 1.0)
        result = run_trial(world, HopController(), 10.0, control_period=0.02)
    finally:
        world.close()
    assert result.fell


def upright_under_pushes(gain_changes, episodes):
    """end_to_end (5 ms) with 0.3 m/s pushes, evaluation seed 1000: each episode's upright-the-whole-10-s."""
    env = make_env(END_TO_END, params=with_push(END_TO_END.default_params(), 0.3), backend="direct", seed=1000)
    try:
        policy, upright = ControllerPolicy(env, gain_changes=gain_changes), []
        observation, _ = env.reset(seed=1000)
        for _ in range(episodes):
            policy.reset()
            terminated = truncated = False
            while not (terminated or truncated):
                observation, _, terminated, truncated, _ = env.step(policy(observation))
            upright.append(not terminated)
            observation, _ = env.reset()
    finally:
        env.close()
    return upright


def test_at_5_ms_a_lower_speed_gain_takes_the_pushes_raiberts_default_falls_to():
    """FIVE_MS_GAIN_CHANGES (the teacher's): the default placement_kv of 0.2 s over-corrects a push at 5 ms."""
    assert upright_under_pushes({}, 1) == [False]
    assert upright_under_pushes(FIVE_MS_GAIN_CHANGES, 3) == [True, True, True]


# -- evaluate.py --policy controller ----------------------------------------------------------------------
def test_evaluate_runs_the_controller_policy_with_the_keys_of_greedy(capsys):
    hopper = TASKS[1]
    code = evaluation.main(["--policy", "controller", "--task", hopper.name, "--speed", "0.4", "--episodes", "1",
                            "--horizon-s", "1.0"], TASKS, "evaluate_monoped",
                           {"controller": ScriptedPolicy(controller_params, ControllerPolicy)})
    assert code == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    empty = Episode(steps=1, return_=0.0, terminated=False, duration=0.0, info={})
    greedy_keys = {**aggregate({"return": [0.0]}), **aggregate({k: [v] for k, v in hopper.metrics(empty).items()})}
    assert report["policy"] == "controller" and report["speed"] == 0.4
    assert report["horizon_s"] == pytest.approx(1.0) and report["initial_tilt"] == [0.02, 0.05]
    assert set(report["controller"]) == set(greedy_keys)
    assert report["controller"]["upright_whole_horizon_rate"] == 1.0 and report["controller"]["mean_hops"] >= 2


def test_evaluate_needs_a_run_for_greedy_and_none_for_a_scripted_policy(capsys):
    policies = {"controller": ScriptedPolicy(controller_params, ControllerPolicy)}
    for argv in (["--episodes", "1"], ["--policy", "controller", "--qtable", "x"]):
        with pytest.raises(SystemExit) as exit_info:
            evaluation.main(argv, TASKS, "evaluate_monoped", policies)
        assert exit_info.value.code == 2
        assert "--qtable RUN is needed for the greedy policy, and only for it" in capsys.readouterr().err
