"""evaluate.py --push: the seeded push schedule, the kick on the direct backend, and the wrapper that applies it."""
import math

import numpy as np
import pytest

from hopper_training.envs.end_to_end import END_TO_END
from robot_rl import make_env
from robot_rl.evaluation import PUSH_GAP_S, Pushes, kick_base, push_schedule


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
    kick_base(env, (0.3, -0.4))
    after = world.model_state()
    assert np.allclose(np.subtract(after.linear_velocity, before.linear_velocity), (0.3, -0.4, 0.0), atol=1e-9)
    assert np.allclose(after.position, before.position, atol=1e-9)
    assert np.allclose(after.angular_velocity, before.angular_velocity, atol=1e-9)
    assert world.read_joint_states() == joints


def test_the_wrapper_kicks_at_the_scheduled_times_only(env, monkeypatch):
    kicks = []
    monkeypatch.setattr("robot_rl.evaluation.kick_base", lambda e, dv: kicks.append((e.unwrapped.readings.stamp, dv)))
    pushed = Pushes(env, 0.3, seed=5, horizon_s=4.0)
    _, info = pushed.reset(seed=5)
    start = info["sim_time"]
    for _ in range(800):  # 4 s at 5 ms
        pushed.step(np.zeros(3, np.float32))
    expected = push_schedule(5, 0, 4.0)
    assert len(kicks) == len(expected) >= 1
    for (stamp, (dx, dy)), (t, heading) in zip(kicks, expected):
        assert 0.0 <= stamp - start - t < env.unwrapped.running_step + 1e-9
        assert (dx, dy) == pytest.approx((0.3 * math.cos(heading), 0.3 * math.sin(heading)))


def test_a_push_changes_the_episode(env):
    """A real push moves the base: 0.5 m/s kicks change the trajectory of the same seeded episode."""
    def x_after(speed):
        wrapped = Pushes(env, speed, seed=2, horizon_s=3.0) if speed else env
        wrapped.reset(seed=2)
        for _ in range(400):
            wrapped.step(np.zeros(3, np.float32))
        return env.unwrapped.backend.world.model_state().position
    assert not np.allclose(x_after(0.5), x_after(0.0), atol=1e-3)


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
