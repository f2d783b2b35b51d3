"""Unit tests for robot_rl.discretiser (no ROS needed)."""
import json
import math

import pytest

from robot_rl import Discretiser

LOW = [-2.5, -1.57, -1.57, -2 * math.pi, 0.0, -1.6, -1.6, -1.6]
HIGH = [2.5, 1.57, 1.57, 2 * math.pi, 14.16, 1.6, 1.6, 0.0]


def hopper():
    return Discretiser(LOW, HIGH, bins=10)


def test_hopper_upright_at_origin():
    # distance 0, roll/pitch/yaw 0, contact force 0, joints 0 (tutorial key "5.05.05.05.01.05.05.010.0")
    d = hopper()
    obs = [0.0] * 8
    assert d.digitise(obs) == (5, 5, 5, 5, 1, 5, 5, 10)
    assert d.key(obs) == "5_5_5_5_1_5_5_10"


def test_negative_zero_same_key():
    d = hopper()
    assert d.key([-0.0] * 8) == d.key([0.0] * 8)


def test_out_of_range_maps_to_end_bins():
    d = hopper()
    below = [lo - 1.0 for lo in LOW]
    above = [hi + 1.0 for hi in HIGH]
    assert d.digitise(below) == (0,) * 8
    assert d.digitise(above) == (10,) * 8
    assert d.digitise([math.inf] * 8) == (10,) * 8


def test_indices_subset_and_per_dimension_bins():
    d = Discretiser([-1.0, 0.0], [1.0, 10.0], bins=[3, 11], indices=[0, 4])
    obs = [0.1, 99.0, -99.0, math.nan, 5.0]  # unused dims may hold anything, even NaN
    assert d.key(obs) == "2_6"
    with pytest.raises(ValueError, match="indices"):
        d.key([0.0, 0.0, 0.0])


def test_nan_raises_naming_dimension():
    obs = [0.0] * 8
    obs[3] = math.nan
    with pytest.raises(ValueError, match="dimension 3"):
        hopper().key(obs)


def test_length_mismatch_raises():
    with pytest.raises(ValueError, match="8"):
        hopper().key([0.0] * 7)


def test_bad_construction():
    with pytest.raises(ValueError):
        Discretiser([0.0], [1.0], bins=1)
    with pytest.raises(ValueError):
        Discretiser([0.0, 0.0], [1.0], bins=5)
    with pytest.raises(ValueError):
        Discretiser([1.0], [0.0], bins=5)
    with pytest.raises(ValueError):
        Discretiser([math.nan], [1.0], bins=5)


def test_to_dict_is_json_and_names_the_edges():
    d = Discretiser([-1.0, 0.0], [1.0, 10.0], bins=[3, 11], indices=[0, 4])
    saved = json.loads(json.dumps(d.to_dict()))
    assert saved["format"] == "robot_rl.discretiser/1" and saved["indices"] == [0, 4]
    assert saved["edges"][0] == [-1.0, 0.0, 1.0]


def test_bins_are_numpy_digitize_bins():
    """The keys of saved Q-tables must not move: every value, on an edge or between, and +-inf, gets
    numpy.digitize's bin, for linspace and explicit edges."""
    import numpy as np
    rng = np.random.default_rng(0)
    d = Discretiser(LOW, HIGH, bins=10)
    explicit = Discretiser.from_edges([[0.0], [10.0 ** e for e in range(-6, 0)], [-0.3, -0.02]])
    for discretiser in (d, explicit):
        edges = discretiser.to_dict()["edges"]
        for _ in range(200):
            obs = [float(rng.choice(e)) if rng.random() < 0.3 else float(rng.uniform(e[0] - 1.0, e[-1] + 1.0))
                   for e in edges]
            obs[int(rng.integers(len(obs)))] = float(rng.choice([math.inf, -math.inf, -0.0]))
            assert discretiser.digitise(obs) == tuple(int(np.digitize(v, e)) for v, e in zip(obs, edges))
        float32_obs = np.array([e[len(e) // 2] for e in edges], dtype=np.float32)
        assert discretiser.digitise(float32_obs) == tuple(
            int(np.digitize(v, e)) for v, e in zip(float32_obs.astype(float), edges))
