"""The training node's private params (robot_rl.training_node.NodeParams), validated as the tasks' are:
no master needed."""
import os
from pathlib import Path

import pytest

from robot_rl import MAX_ENVS_PER_CORE, NodeParams, ParamError


def test_defaults():
    node = NodeParams.from_mapping({}, "/node")
    assert (node.envs, node.max_steps, node.timeout, node.resume, node.run, node.agent) == (1, 0, 10.0, False, "",
                                                                                           "qlearn")


@pytest.mark.parametrize("values, expected", [
    ({"envs": "abc"}, "/node: parameter 'envs' expected int, got 'abc' (str)"),
    ({"envs": MAX_ENVS_PER_CORE * (os.cpu_count() or 1) + 1}, "per core"),
    ({"max_steps": -1}, "parameter 'max_steps' = -1 out of range"),
    ({"timeout": 0.0}, "parameter 'timeout' = 0.0 out of range (0.0, 3600.0]"),
    ({"resume": "yes"}, "parameter 'resume' expected bool"),
])
def test_bad_values_get_one_line(values, expected):
    with pytest.raises(ParamError, match=expected.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")) as error:
        NodeParams.from_mapping(values, "/node")
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("results_dir, expected", [
    ("runs", "launched/runs"), ("~/runs", "home/runs"), ("/abs/runs", "/abs/runs")])
def test_a_results_dir_is_resolved_where_roslaunch_ran(tmp_path, monkeypatch, results_dir, expected):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    node = NodeParams.from_mapping({"results_dir": results_dir, "launch_dir": str(tmp_path / "launched")}, "/node")
    assert node.results_root == (Path(expected) if expected.startswith("/") else tmp_path / expected)
