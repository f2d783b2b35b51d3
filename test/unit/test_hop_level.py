"""Unit tests of the monoped's hop-level task (MonopedHopInPlace-v0) on the direct backend (no ROS master): a step
ends at the next decision point (lift-off), the actions' offsets and thrusts, the state key's bins, the
truncation at the horizon, gymnasium's env checker; and the controller's hooks for it."""
import dataclasses
import json
import math

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from hopper_training import TASKS
from hopper_training.controller.core import HopController, HopGains, HopInput, Phase
from hopper_training.envs.end_to_end import END_TO_END
from hopper_training.envs.hop_cycle import controller_params
from hopper_training.envs.hop_in_place import (
    COARSE_SPEED_EDGES,
    HOP_IN_PLACE,
    SPEED_EDGES,
    HopInPlaceStateKey,
    SpeedStateKey,
    action_meaning,
    do_nothing_action,
    offsets,
    thrust_knees,
)
from hopper_training.scripted_policies import POLICIES
from robot_rl import ParamError, evaluation, make_env
from robot_rl.params import TableSelection

PARAMS = HOP_IN_PLACE.default_params()


@pytest.fixture
def env():
    made = make_env(HOP_IN_PLACE, params=PARAMS, backend="direct", seed=0)
    yield made
    made.close()


def test_the_actions_are_offsets_times_thrusts_and_do_nothing_is_offset_0_default_thrust():
    assert offsets(PARAMS) == pytest.approx([-0.02, 0.0, 0.02, 0.04, 0.06, 0.08])
    assert thrust_knees(PARAMS) == [0.0]
    assert action_meaning(PARAMS, do_nothing_action(PARAMS)) == pytest.approx((0.0, 0.0))
    two = PARAMS.with_changes("test", offset_min=-0.02, offset_max=0.06, offset_levels=5, thrust_min=-0.2,
                              thrust_levels=2)
    meanings = [value for a in range(10) for value in action_meaning(two, a)]
    assert meanings == pytest.approx([v for o in (-0.02, 0.0, 0.02, 0.04, 0.06) for t in (-0.2, 0.0) for v in (o, t)])
    assert action_meaning(two, do_nothing_action(two)) == pytest.approx((0.0, 0.0)) and do_nothing_action(two) == 3


def test_params_without_a_do_nothing_action_are_refused():
    with pytest.raises(ParamError, match="no offset level is 0"):
        PARAMS.with_changes("test", offset_min=0.01)
    with pytest.raises(ParamError, match="'default_thrust' .* is not one of the thrust levels"):
        PARAMS.with_changes("test", thrust_min=-0.2, thrust_levels=2, default_thrust=-0.1)


def test_the_push075_config_is_the_push_config_with_its_marked_keys_alone():
    folder = HOP_IN_PLACE.config_path.parent
    pushed = HOP_IN_PLACE.load_params(folder / "hop_in_place_push.yaml")
    strong = HOP_IN_PLACE.load_params(folder / "hop_in_place_push075.yaml")
    marked = {"alpha": 0.03, "gamma": 0.8, "epsilon_discount": 0.995, "epsilon_min": 0.02, "q_init": 14.0,
              "nepisodes": 1200, "push_speed": 0.75, "offset_min": 0.0, "offset_max": 0.06, "offset_levels": 4,
              "speed_weight": 2.0, "selection": TableSelection(every=100, episodes=20, seed=500)}
    assert strong == dataclasses.replace(pushed, **marked)
    assert offsets(strong) == pytest.approx([0.0, 0.02, 0.04, 0.06])
    text = (folder / "hop_in_place_push075.yaml").read_text()
    assert sorted(line.split(":")[0] for line in text.splitlines() if "# push075:" in line) == sorted(marked)


def test_the_push075_speed_config_is_the_push075_config_with_its_marked_keys_alone():
    folder = HOP_IN_PLACE.config_path.parent
    strong = HOP_IN_PLACE.load_params(folder / "hop_in_place_push075.yaml")
    by_speed = HOP_IN_PLACE.load_params(folder / "hop_in_place_push075_speed.yaml")
    marked = {"nepisodes": 600, "state_key": "speed"}
    assert by_speed == dataclasses.replace(strong, **marked)
    text = (folder / "hop_in_place_push075_speed.yaml").read_text()
    assert sorted(line.split(":")[0] for line in text.splitlines() if "# speed:" in line) == sorted(marked)


def test_the_state_key_bins_speed_and_the_sign_of_the_lean_along_the_velocity():
    key = HopInPlaceStateKey(PARAMS)

    def of(speed, lean):
        return key.key(np.array([0.0, 0.0, speed, lean, 0.0, 0.0, 0.9, 0.3], dtype=np.float32))
    speeds = [0.0, 0.03, 0.07, 0.12, 0.17, 0.25, 0.4, 2.0]  # one in each speed bin
    keys = {of(s, lean) for s in speeds for lean in (-0.2, 0.2)}
    assert len(keys) == (len(SPEED_EDGES) + 1) * 2 == 16
    assert of(0.06, 0.01) == of(0.09, 0.3) != of(0.11, 0.3)
    assert of(0.0, 0.01) != of(0.0, -0.01)


def test_state_key_speed_bins_the_speed_alone():
    params = PARAMS.with_changes("test", state_key="speed")
    key = HOP_IN_PLACE.state_key(params)
    assert isinstance(key, SpeedStateKey)

    def of(speed, lean):
        return key.key(np.array([0.0, 0.0, speed, lean, 0.0, 0.0, 0.9, 0.3], dtype=np.float32))
    assert len({of(s, 0.1) for s in (0.0, 0.2, 0.3, 0.6, 2.0)}) == len(COARSE_SPEED_EDGES) + 1 == 5
    assert of(0.2, -0.3) == of(0.12, 0.3) != of(0.3, 0.3)
    assert key.to_dict() != HOP_IN_PLACE.state_key(PARAMS).to_dict()  # a table of one is refused by the other


def test_a_step_runs_the_hop_cycle_from_lift_off_to_the_next_lift_off(env):
    unwrapped = env.unwrapped
    env.reset(seed=1)
    controller, phases = unwrapped.controller, []
    update = controller.update

    def watched(reading):
        targets = update(reading)
        phases.append(controller.phase)
        return targets
    controller.update = watched
    for _ in range(4):
        phases.clear()
        observation, reward, terminated, truncated, info = env.step(do_nothing_action(PARAMS))
        assert not (terminated or truncated)
        # one control period per update, and the step ends on the update that entered FLIGHT from stance
        assert len(phases) == round(info["hop_time"] / PARAMS.running_step)
        assert phases[-1] is Phase.FLIGHT and phases[-2] is not Phase.FLIGHT
        assert Phase.THRUST in phases and phases.count(Phase.FLIGHT) < len(phases)
        assert 0.05 < info["hop_time"] < PARAMS.max_hop_s  # the first, from standing, is the shortest
        velocities = unwrapped.velocities  # the last 5 readings', all in the air
        assert len(velocities) == 5 and not unwrapped.readings.contact("lowerleg_contactsensor_sensor").contacts
        speed = math.hypot(*np.mean(velocities, axis=0))
        assert observation[2] == pytest.approx(speed, rel=1e-5)
        assert reward == pytest.approx(PARAMS.alive_reward * info["hop_time"] - PARAMS.speed_weight * speed, abs=1e-5)


def test_the_action_sets_the_placement_offset_along_the_velocity_and_the_thrust(env):
    unwrapped = env.unwrapped
    observation, _ = env.reset(seed=2)
    env.step(do_nothing_action(PARAMS))
    env.step(do_nothing_action(PARAMS))  # from the first touchdown on, the thrust is the action's
    velocity = np.mean(unwrapped.velocities, axis=0)
    direction = velocity / math.hypot(*velocity)
    action = 4  # offset 0.06
    unwrapped._apply_action(action, unwrapped.readings)
    assert unwrapped.controller.placement_offset == pytest.approx(list(0.06 * direction))
    assert unwrapped.controller.thrust_knee == 0.0
    _, _, _, _, info = env.step(action)
    assert (info["offset"], info["thrust_knee"]) == pytest.approx((0.06, 0.0))


def test_a_thrust_action_sets_the_next_stances_thrust():
    params = PARAMS.with_changes("test", thrust_min=-0.2, thrust_levels=2)
    made = make_env(HOP_IN_PLACE, params=params, backend="direct", seed=0)
    try:
        made.reset(seed=2)
        made.step(do_nothing_action(params))
        made.step(2)  # offset 0, thrust -0.2 (from the first touchdown on, the thrust is the action's)
        assert made.unwrapped.controller.thrust_knee == pytest.approx(-0.2)
        made.step(3)
        assert made.unwrapped.controller.thrust_knee == 0.0
    finally:
        made.close()


def test_the_episode_is_truncated_at_the_horizon_in_sim_time():
    made = make_env(HOP_IN_PLACE, params=controller_params(PARAMS), backend="direct", seed=0, max_episode_steps=600)
    try:
        made.reset(seed=3)
        times, truncated = [], False
        while not truncated:
            _, _, terminated, truncated, info = made.step(do_nothing_action(PARAMS))
            assert not terminated
            times.append(info["episode_time"])
        assert times[-1] == pytest.approx(0.6, abs=1e-6) and all(t < 0.6 for t in times[:-1])
        assert len(times) < 600 / 50  # steps are hops, not control periods
    finally:
        made.close()


def test_gymnasiums_env_checker_passes(env):
    check_env(env.unwrapped, skip_render_check=True)
    assert env.action_space == gymnasium.spaces.Discrete(6)


def _flight_reading(vx):
    return HopInput(time=1.0, joint_position=(0.0, 0.4, -0.6), joint_velocity=(0.0, 0.0, 0.0),
                    orientation=(0.0, 0.0, 0.0, 1.0), angular_velocity=(0.0, 0.0, 0.0), position=(0.0, 0.0, 1.0),
                    linear_velocity=(vx, 0.0, 0.0), contact=False)


def test_the_controllers_hooks_leave_it_unchanged_by_default_and_take_the_feedback_out():
    def hips(gains, offset=(0.0, 0.0)):
        controller = HopController(gains)
        controller._started = True  # in the air, not the standing start
        controller.placement_offset = list(offset)
        return controller.update(_flight_reading(0.3))[:2]
    default = hips(HopGains())
    assert hips(HopGains(speed_feedback=True, neutral_point=True)) == default
    no_feedback = hips(HopGains(speed_feedback=False))
    bare = hips(HopGains(speed_feedback=False, neutral_point=False))
    assert no_feedback != pytest.approx(default) and bare != pytest.approx(no_feedback)
    # with the neutral point and feedback off, an offset of v T_s/2 + k_v v along x is the controller's placement
    gains = HopGains()
    assert hips(HopGains(speed_feedback=False, neutral_point=False),
                (0.3 * gains.stance_time / 2.0 + gains.placement_kv * 0.3, 0.0)) == pytest.approx(default)
    assert dataclasses.replace(gains).speed_feedback and gains.neutral_point


# -- evaluate.py --policy constant: one action every hop, the trivial baselines ------------------------------
def evaluate_json(capsys, *argv: str) -> dict:
    assert evaluation.main(list(argv), TASKS, "evaluate_monoped") == 0
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_evaluate_plays_one_constant_action_every_hop(capsys):
    report = evaluate_json(capsys, "--policy", "constant", "--action", "2", "--task", "hop_in_place",
                           "--episodes", "1", "--horizon-s", "2")
    assert report["policy"] == "constant" and report["action"] == 2 and report["task"] == HOP_IN_PLACE.env_id
    assert report["constant"]["mean_hops"] >= 5 and report["constant"]["upright_whole_horizon_rate"] == 1.0
    assert action_meaning(PARAMS, 2) == pytest.approx((0.02, 0.0)), "action 2: the foot 2 cm ahead"


def test_placement_by_speed_puts_the_foot_further_ahead_the_faster_the_robot_goes(env, capsys):
    policy = POLICIES["placement_by_speed"].build(env, 0.0)
    at_speed = [np.array([s, 0.0, s, 0.0, 0.0, 0.0, 0.6, 0.3], dtype=np.float32) for s in (0.0, 0.4, 0.6, 1.4, 1.6)]
    assert [action_meaning(PARAMS, policy(o)) for o in at_speed] == [
        pytest.approx((offset, 0.0)) for offset in (0.02, 0.02, 0.04, 0.04, 0.06)]
    with pytest.raises(ValueError, match="hops in place: --speed must be 0, got 0.3"):
        POLICIES["placement_by_speed"].build(env, 0.3)
    assert evaluation.main(["--policy", "placement_by_speed", "--task", "hop_in_place", "--episodes", "1",
                            "--horizon-s", "2"], TASKS, "evaluate_monoped", POLICIES) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert report["placement_by_speed"]["mean_hops"] >= 5


def test_placement_by_speed_is_for_hop_in_place_only():
    end_to_end = make_env(END_TO_END, backend="direct", seed=0)
    try:
        with pytest.raises(ValueError, match="--policy placement_by_speed is for --task hop_in_place"):
            POLICIES["placement_by_speed"].build(end_to_end, 0.0)
    finally:
        end_to_end.close()


def test_evaluate_plays_a_constant_box_action_and_end_to_end_does_nothing_by_holding_the_crouch(capsys):
    report = evaluate_json(capsys, "--policy", "constant", "--action", "0,0.5,0", "--task", "end_to_end",
                           "--episodes", "1", "--horizon-s", "0.5")
    assert report["action"] == "0,0.5,0" and report["task"] == "MonopedEndToEnd-v0"
    assert evaluation.main(["--policy", "do_nothing", "--task", "end_to_end", "--episodes", "1", "--horizon-s", "0.5"],
                           TASKS, "evaluate_monoped", POLICIES) == 0
    still = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert still["do_nothing"]["mean_hops"] == 0


@pytest.mark.parametrize("argv, message", [
    (["--policy", "constant", "--task", "hop_in_place"], "--action N is needed for --policy constant, and only for it"),
    (["--qtable", "some_run", "--action", "1"], "--action N is needed for --policy constant, and only for it"),
    (["--policy", "constant", "--action", "6", "--task", "hop_in_place"],
     "--action must be from 0 to 5 (MonopedHopInPlace-v0's Discrete(6)), got 6"),
    (["--policy", "constant", "--action", "0", "--task", "residual_forward"],
     "--action must be 2 comma-separated numbers within MonopedResidualForward-v0's Box("),
    (["--policy", "constant", "--action", "0,0,7", "--task", "end_to_end"],
     "--action must be 3 comma-separated numbers within MonopedEndToEnd-v0's Box("),
    (["--policy", "constant", "--action", "x", "--task", "hop_in_place"],
     "--action must be from 0 to 5 (MonopedHopInPlace-v0's Discrete(6)), got x"),
])
def test_evaluate_refuses_a_constant_action_the_task_cannot_take_in_one_line(capsys, argv, message):
    with pytest.raises(SystemExit) as exit_info:
        evaluation.main([*argv, "--episodes", "1"], TASKS, "evaluate_monoped")
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("name", ["hop_in_place", "residual_in_place", "residual_forward"])
def test_a_running_step_the_hop_cycle_cannot_use_is_refused_naming_the_bound(name):
    """running_step: 0.5 "completed" 150 episodes of 2 steps; the controller falls from a 10 ms period."""
    from robot_rl import find_task
    task = find_task(list(TASKS), name)
    with pytest.raises(ParamError, match=r"^src: parameter 'running_step' = 0.5 out of range \(0.0, 0.005\]$"):
        task.default_params().with_changes("src", running_step=0.5)
    assert task.default_params().with_changes("src", running_step=0.005).running_step == 0.005
