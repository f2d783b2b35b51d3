"""Unit tests for robot_rl.qlearn (no ROS needed)."""
import json

import pytest

from robot_rl import QLearn

ACTIONS = [0, 1, 2, 3, 4]


def make(epsilon=0.0, seed=0):
    return QLearn(ACTIONS, epsilon=epsilon, alpha=0.5, gamma=0.9, seed=seed)


def test_first_visit_stores_reward_not_target():
    ql = make()
    ql.q[("s2", 3)] = 10.0
    ql.learn("s1", 0, 2.0, "s2")
    assert ql.getQ("s1", 0) == 2.0


def test_update_rule_for_seen_pair():
    ql = make()
    ql.q[("s1", 0)] = 1.0
    ql.q[("s2", 1)] = 4.0
    ql.q[("s2", 2)] = -3.0
    ql.learn("s1", 0, 2.0, "s2")
    # target = 2 + 0.9 * 4 = 5.6; Q = 1 + 0.5 * (5.6 - 1) = 3.3
    assert ql.getQ("s1", 0) == pytest.approx(3.3)


def test_terminal_drops_bootstrap():
    ql = make()
    ql.q[("s1", 0)] = 1.0
    ql.q[("s2", 1)] = 4.0
    ql.learn("s1", 0, 2.0, "s2", terminal=True)
    # target = 2; Q = 1 + 0.5 * (2 - 1) = 1.5
    assert ql.getQ("s1", 0) == pytest.approx(1.5)


def test_unseen_q_is_zero():
    assert make().getQ("nowhere", 2) == 0.0


def test_epsilon_zero_picks_argmax():
    ql = make(epsilon=0.0)
    ql.q[("s", 3)] = 1.0
    ql.q[("s", 1)] = 0.5
    assert all(ql.chooseAction("s") == 3 for _ in range(100))
    assert ql.greedy_action("s") == 3
    action, q = ql.chooseAction("s", return_q=True)
    assert action == 3 and q == [0.0, 0.5, 0.0, 1.0, 0.0]


def test_epsilon_one_explores_with_nonzero_q():
    ql = make(epsilon=1.0)
    for a, v in zip(ACTIONS, [1.0, 0.5, 0.0, -0.5, -1.0]):
        ql.q[("s", a)] = v
    chosen = [ql.chooseAction("s") for _ in range(1000)]
    assert len(set(chosen)) >= 2
    assert max(set(chosen), key=chosen.count) == 0
    assert ql.greedy_action("s") == 0


def test_all_zero_q_ties_broken_among_all_actions():
    ql = make(epsilon=1.0)
    chosen = {ql.chooseAction("s") for _ in range(500)}
    assert chosen == set(ACTIONS)
    greedy = make(epsilon=0.0)
    assert {greedy.greedy_action("s") for _ in range(500)} == set(ACTIONS)


def test_same_seed_same_sequence_different_seed_differs():
    def seq(seed):
        ql = make(epsilon=0.5, seed=seed)
        ql.q[("s", 1)] = 1.0
        return [ql.chooseAction(st) for _ in range(100) for st in ("s", "t")]

    assert seq(7) == seq(7)
    assert seq(7) != seq(8)


def test_json_round_trip_continues_the_same_choices():
    ql = QLearn(ACTIONS, epsilon=0.3, alpha=0.2, gamma=0.8, seed=42)
    states = ["0_1", "1_1", "2_0", "-1_3"]
    for i in range(200):
        s1, s2 = states[i % 4], states[(i + 1) % 4]
        ql.learn(s1, ql.chooseAction(s1), (i % 7) / 3.0 - 1.0, s2, terminal=i % 13 == 0)
    loaded = QLearn.from_dict(json.loads(json.dumps(ql.to_dict())))  # as a checkpoint saves and loads it
    assert loaded.q == ql.q
    assert (loaded.actions, loaded.epsilon, loaded.alpha, loaded.gamma) == \
        (ql.actions, ql.epsilon, ql.alpha, ql.gamma)
    assert [loaded.chooseAction(states[i % 4]) for i in range(100)] == \
        [ql.chooseAction(states[i % 4]) for i in range(100)]


def test_to_dict_sorted_and_from_dict_round_trip():
    ql = make()
    ql.q[("b", 1)] = 1.0
    ql.q[("a", 2)] = 2.0
    ql.q[("a", 0)] = 3.0
    d = ql.to_dict()
    assert d["format"] == "robot_rl.qlearn/1"
    assert d["q"] == [["a", 0, 3.0], ["a", 2, 2.0], ["b", 1, 1.0]]
    assert QLearn.from_dict(json.loads(json.dumps(d))).q == ql.q


def test_from_dict_rejects_wrong_format():
    d = make().to_dict()
    d["format"] = "something/else"
    with pytest.raises(ValueError, match="format"):
        QLearn.from_dict(d)
    with pytest.raises(ValueError, match="format"):
        QLearn.from_dict({"q": []})


def tried_actions(ql, visits, reward=100.0):
    """Visit one new state `visits` times, learning a positive reward for whatever is chosen."""
    tried = []
    for _ in range(visits):
        action = ql.chooseAction("new")
        tried.append(action)
        ql.learn("new", action, reward, "next")
    return tried


def test_epsilon_greedy_tries_every_action_of_a_new_state_within_bounded_visits():
    ql = QLearn(range(6), epsilon=0.3, alpha=0.2, gamma=0.98, seed=5, exploration="epsilon_greedy")
    tried = tried_actions(ql, 100)
    # with probability 0.3 a uniform action: missing one of 6 in 100 visits has probability < 6 * (1 - 0.05)^100
    assert set(tried) == set(range(6))
    assert len(set(tried[:60])) == 6


def test_optimistic_initial_values_try_every_action_greedily():
    """Unseen pairs are worth q_init; a first visit steps from it, so each action is tried once first."""
    ql = QLearn(range(6), epsilon=0.0, alpha=0.2, gamma=0.98, seed=5, exploration="epsilon_greedy",
                q_init=5000.0, first_visit="target")
    assert sorted(tried_actions(ql, 6, reward=0.0)) == list(range(6))
    assert ql.getQ("new", 0) == pytest.approx(5000.0 + 0.2 * (0.0 + 0.98 * 5000.0 - 5000.0))


def test_the_tutorials_noise_never_tries_an_untried_action_when_rewards_are_positive():
    """Why the monoped did not learn with the tutorial's rule: noise of +/- half the largest |Q| cannot lift
    an untried action (Q = 0) above a tried one (Q = its positive first reward)."""
    ql = QLearn(range(6), epsilon=0.9, alpha=0.1, gamma=0.8, seed=5)
    assert len(set(tried_actions(ql, 500))) == 1


def test_a_visits_step_size_averages_q_init_and_the_targets_until_the_step_comes_down_to_alpha():
    ql = QLearn(range(2), 0.0, alpha=0.2, gamma=0.9, q_init=10.0, first_visit="target", step_size="visits")
    for value in (4.0, 7.0, 1.0):
        ql.learnQ("s", 0, 0.0, value)
    assert ql.getQ("s", 0) == pytest.approx((10.0 + 4.0 + 7.0 + 1.0) / 4)  # steps 1/2, 1/3, 1/4
    ql.learnQ("s", 0, 0.0, 0.0)  # 1/5 = alpha
    ql.learnQ("s", 0, 0.0, 0.0)  # 1/6 < alpha: alpha
    assert ql.getQ("s", 0) == pytest.approx(5.5 * 0.8 * 0.8)
    assert ql.visits == {("s", 0): 5} and ql.getQ("s", 1) == 10.0


def test_a_constant_step_size_counts_no_visits():
    ql = QLearn(range(2), 0.0, alpha=0.2, gamma=0.9, q_init=10.0, first_visit="target")
    ql.learnQ("s", 0, 0.0, 0.0)
    ql.learnQ("s", 0, 0.0, 0.0)
    assert ql.getQ("s", 0) == pytest.approx(10.0 * 0.8 * 0.8) and ql.visits == {}


@pytest.mark.parametrize("exploration, first_visit, step_size",
                         [("epsilon_greedy", "target", "visits"), ("noise", "reward", "constant")])
def test_the_choices_are_saved_with_the_table(exploration, first_visit, step_size):
    ql = QLearn(range(3), 0.2, 0.1, 0.9, seed=1, exploration=exploration, q_init=7.5, first_visit=first_visit,
                step_size=step_size)
    ql.learn("s", 1, 1.0, "t")
    ql.learn("s", 1, 1.0, "t")
    loaded = QLearn.from_dict(json.loads(json.dumps(ql.to_dict())))
    assert (loaded.exploration, loaded.q_init, loaded.first_visit, loaded.step_size) == \
        (exploration, 7.5, first_visit, step_size)
    assert loaded.q == ql.q and loaded.visits == ql.visits == ({("s", 1): 2} if step_size == "visits" else {})


def test_unknown_choices_are_refused():
    with pytest.raises(ValueError, match="exploration"):
        QLearn(range(3), 0.2, 0.1, 0.9, exploration="softmax")
    with pytest.raises(ValueError, match="step_size one of"):
        QLearn(range(3), 0.2, 0.1, 0.9, step_size="harmonic")
