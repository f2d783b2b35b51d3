"""Pushes (robot_rl.envs.pushes): the seeded schedule, the kick on the direct backend, the env that applies it in
training and in evaluate.py --push."""
import math

import numpy as np
import pytest

from hopper_training.envs.end_to_end import END_TO_END
from hopper_training.envs.hop_in_place import HOP_IN_PLACE
from robot_rl import ParamError, make_env
from robot_rl.envs.pushes import PUSH_GAP_S, PushPlan, push_schedule


def test_the_schedule_is_seeded_reproducible_and_about_one_push_every_2_s():
    assert push_schedule(1000, 3, 10.0) == push_schedule(1000, 3, 10.0)
    assert push_schedule(1000, 3, 10.0) != push_schedule(1000, 4, 10.0) != push_schedule(1001, 3, 10.0)
    long = push_schedule(0, 0, 2000.0)
    gaps = np.diff([0.0] + [t for t, _ in long])
    assert 950 <= len(long) <= 1050 and gaps.min() >= PUSH_GAP_S[0] and gaps.max() <= PUSH_GAP_S[1]
    headings = np.array([h for _, h in long])
    assert headings.min() >= -math.pi and headings.max() <= math.pi and abs(np.mean(np.cos(headings))) < 0.1
    assert all(t < 10.0 for t, _ in push_schedule(7, 0, 10.0))


@pytest.fixture
def env():
    made = make_env(END_TO_END, backend="direct", seed=0)
    yield made
    made.close()


def test_a_kick_adds_horizontal_base_velocity_and_leaves_the_rest(env):
    env.reset(seed=0)
    world = env.unwrapped.backend.world
    before, joints = world.model_state(), world.read_joint_states()
    env.unwrapped.backend.kick((0.3, -0.4))
    after = world.model_state()
    assert np.allclose(np.subtract(after.linear_velocity, before.linear_velocity), (0.3, -0.4, 0.0), atol=1e-9)
    assert np.allclose(after.position, before.position, atol=1e-9)
    assert np.allclose(after.angular_velocity, before.angular_velocity, atol=1e-9)
    assert world.read_joint_states() == joints


def test_the_plan_numbers_episodes_from_the_last_seeded_reset():
    plan = PushPlan(0.3)
    plan.start_episode(0.0, seed=5)
    assert (plan.seed, plan.episode) == (5, 0)
    plan.start_episode(12.0, seed=None)
    assert (plan.seed, plan.episode) == (5, 1)
    (t, heading), *_ = push_schedule(5, 1, 10.0)
    assert plan.due(12.0 + t - 1e-6) == []
    assert plan.due(12.0 + t) == [pytest.approx((0.3 * math.cos(heading), 0.3 * math.sin(heading)))]
    assert plan.due(12.0 + t) == []
    calm = PushPlan(0.0)
    calm.start_episode(0.0, seed=5)
    assert calm.due(1000.0) == []


def pushed_env(task, speed, seed=5):
    params = task.default_params().with_changes("test", push_speed=speed)
    return make_env(task, params=params, backend="direct", seed=seed)


def test_the_env_kicks_at_the_scheduled_times_only(monkeypatch):
    env = pushed_env(END_TO_END, 0.3)
    kicks = []
    monkeypatch.setattr(env.unwrapped.backend, "kick", lambda dv: kicks.append((env.unwrapped.readings.stamp, dv)))
    try:
        env.reset(seed=5)  # evaluate.py's first reset: episode 0 of seed 5
        _, info = env.reset()  # episode 1
        start = info["sim_time"]
        for _ in range(800):  # 4 s at 5 ms
            env.step(np.zeros(3, np.float32))
    finally:
        env.close()
    expected = push_schedule(5, 1, 4.0)
    assert len(kicks) == len(expected) >= 1
    for (stamp, (dx, dy)), (t, heading) in zip(kicks, expected):
        assert 0.0 <= stamp - start - t < env.unwrapped.running_step + 1e-9
        assert (dx, dy) == pytest.approx((0.3 * math.cos(heading), 0.3 * math.sin(heading)))


def test_a_hop_long_step_is_pushed_mid_step_and_the_base_velocity_jumps_by_the_push():
    """hop_in_place (one step a hop, ~270 control periods): the base's horizontal velocity jumps by 0.3 m/s in the
    drawn direction in the control period of the push's time, not at the next step."""
    env = pushed_env(HOP_IN_PLACE, 0.3, seed=3)
    world = env.unwrapped.backend.world
    velocities = []
    env.unwrapped.period_hooks.append(lambda: velocities.append((world.time, world.model_state().linear_velocity)))
    try:
        env.reset(seed=3)
        start = env.unwrapped.readings.stamp
        (t, heading), *_ = push_schedule(3, 0, 10.0)
        truncated = terminated = False
        while velocities[-1][0] - start < t + 0.01 if velocities else True:
            _, _, terminated, truncated, _ = env.step(0)
            assert not (terminated or truncated)
    finally:
        env.close()
    times = [stamp - start for stamp, _ in velocities]
    i = 1 + next(i for i, s in enumerate(times) if s >= t - 1e-9)  # the first period that starts at or after t
    jump = np.subtract(velocities[i][1], velocities[i - 1][1])[:2]
    normal = [np.subtract(velocities[k][1], velocities[k - 1][1])[:2] for k in range(1, i)]
    assert np.dot(jump, (math.cos(heading), math.sin(heading))) == pytest.approx(0.3, abs=0.05)
    assert np.linalg.norm(jump) > 0.25 > 3 * max(np.linalg.norm(d) for d in normal)


def test_a_push_changes_the_episode():
    """A real push moves the base: 0.5 m/s kicks change the trajectory of the same seeded episode."""
    def x_after(speed):
        env = pushed_env(END_TO_END, speed, seed=2)
        try:
            env.reset(seed=2)
            for _ in range(400):
                env.step(np.zeros(3, np.float32))
            return env.unwrapped.backend.world.model_state().position
        finally:
            env.close()
    assert not np.allclose(x_after(0.5), x_after(0.0), atol=1e-3)


def test_push_params_are_checked_in_one_line():
    with pytest.raises(ParamError, match="push_interval/low.*must not be above"):
        HOP_IN_PLACE.default_params().with_changes("test", push_interval={"low": 3.0, "high": 1.0})
    with pytest.raises(ParamError, match="'push_speed' = -0.1 out of range"):
        HOP_IN_PLACE.default_params().with_changes("test", push_speed=-0.1)


def test_evaluate_refuses_a_negative_push_in_one_line(capsys):
    import hopper_training
    from hopper_training.scripted_policies import POLICIES
    from robot_rl.evaluation import main
    with pytest.raises(SystemExit) as exit_:
        main(["--policy", "random", "--push", "-0.1"], hopper_training.TASKS, "evaluate_test", POLICIES)
    assert exit_.value.code == 2 and "--push must be a speed >= 0 (m/s), got -0.1" in capsys.readouterr().err


def test_evaluate_with_pushes_reports_them_and_they_cost_the_teacher_nothing_it_cannot_take(capsys):
    import json

    import hopper_training
    from hopper_training.scripted_policies import POLICIES
    from robot_rl.evaluation import main
    argv = ["--policy", "controller", "--task", "end_to_end", "--episodes", "1", "--horizon-s", "3", "--seed", "1000"]
    assert main([*argv, "--push", "0.3"], hopper_training.TASKS, "evaluate_test", POLICIES) == 0
    pushed = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert main(argv, hopper_training.TASKS, "evaluate_test", POLICIES) == 0
    calm = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert pushed["push"] == 0.3 and "push" not in calm
    assert pushed["controller"]["mean_lateral_drift"] != calm["controller"]["mean_lateral_drift"]


def test_evaluation_sets_the_pushes_it_is_asked_for_whatever_the_run_trained_with():
    from robot_rl.evaluation import with_push
    trained = HOP_IN_PLACE.default_params().with_changes("test", push_speed=0.3,
                                                         push_interval={"low": 0.5, "high": 1.0})
    calm = with_push(trained, 0.0)
    assert calm.push_speed == 0.0
    pushed = with_push(trained, 0.3)
    assert pushed.push_speed == 0.3 and (pushed.push_interval.low, pushed.push_interval.high) == PUSH_GAP_S
