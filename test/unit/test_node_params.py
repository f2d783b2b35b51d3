"""The training node's private params (robot_rl.training_node.NodeParams), validated as the tasks' are:
no master needed."""
import os
from pathlib import Path

import pytest

from robot_rl import MAX_ENVS_PER_CORE, NodeParams, ParamError
from robot_rl.runs.next_steps import WS_RESULTS_VARIABLE
from robot_rl.training_node import _given_launch_args


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


def test_the_launch_arguments_given_are_those_not_their_defaults(tmp_path, monkeypatch):
    """What the end block's "train further" command repeats (robot_rl.training_node._given_launch_args)."""
    monkeypatch.delenv(WS_RESULTS_VARIABLE, raising=False)
    default, other = tmp_path / "end_to_end.yaml", tmp_path / "end_to_end_assist.yaml"
    default.write_text("{}\n")
    other.write_text("{}\n")
    plain = NodeParams.from_mapping({"config_file": str(default), "default_config": str(default)}, "/node")
    assert _given_launch_args(plain) == ()
    assert _given_launch_args(NodeParams.from_mapping({}, "/node")) == (), "params from rosparam alone: no file"
    given = NodeParams.from_mapping({"config_file": str(other), "default_config": str(default),
                                     "agent_config": "ppo.yaml", "backend": "direct", "envs": 2, "cluster": "ray",
                                     "results_dir": "runs"}, "/node")
    assert _given_launch_args(given) == (f"config:={other}", "agent_config:=ppo.yaml", "backend:=direct", "envs:=2",
                                         "cluster:=ray", "results_dir:=runs")
    monkeypatch.setenv(WS_RESULTS_VARIABLE, "runs")
    assert "results_dir:=runs" not in _given_launch_args(given), "./ws run's own default, set by it, not repeated"
