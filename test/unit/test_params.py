"""Unit tests for robot_rl.params (no ROS needed)."""
import pytest

from robot_rl.params import Param, ParamError, flatten, load_yaml_file, validate

SRC = "/ws/config/hopper.yaml"
SPEC = [
    Param("alpha", float, 0.0, 1.0, low_inclusive=False),
    Param("nepisodes", int, 1),
    Param("running_step", float, 0.0, None, low_inclusive=False),
    Param("init_cube_pose/y", float),
    Param("use_gui", bool),
    Param("robot", str),
]
GOOD = {"alpha": 0.1, "nepisodes": 500, "running_step": 0.04, "init_cube_pose/y": 0,
        "use_gui": False, "robot": "hopper"}


def error(values):
    with pytest.raises(ParamError) as info:
        validate(values, SPEC, SRC)
    msg = str(info.value)
    assert msg.startswith(SRC + ": ")
    assert "\n" not in msg
    return msg


def test_valid_and_int_accepted_as_float():
    out = validate(GOOD, SPEC, SRC)
    assert out == {**GOOD, "init_cube_pose/y": 0.0}
    assert type(out["init_cube_pose/y"]) is float
    assert type(out["nepisodes"]) is int
    assert GOOD["init_cube_pose/y"] == 0 and type(GOOD["init_cube_pose/y"]) is int  # input untouched


def test_missing():
    values = dict(GOOD)
    del values["running_step"]
    assert error(values) == f"{SRC}: missing parameter 'running_step'"


@pytest.mark.parametrize("key, bad, expected", [
    ("alpha", "0.1", "float"),
    ("nepisodes", True, "int"),
    ("nepisodes", 1.5, "int"),
    ("nepisodes", 500.0, "int"),
    ("alpha", True, "float"),
    ("use_gui", 1, "bool"),
])
def test_wrong_type(key, bad, expected):
    msg = error({**GOOD, key: bad})
    assert f"'{key}'" in msg
    assert f"expected {expected}" in msg
    assert repr(bad) in msg and type(bad).__name__ in msg


@pytest.mark.parametrize("key, bad", [("alpha", 0.0), ("alpha", 1.5), ("nepisodes", 0),
                                      ("running_step", -0.1)])
def test_out_of_range(key, bad):
    msg = error({**GOOD, key: bad})
    assert f"'{key}'" in msg and repr(bad) in msg and "range" in msg


def test_nan_rejected():
    assert "NaN" in error({**GOOD, "alpha": float("nan")})


def test_flatten():
    assert flatten({"a": {"b": 1}}) == {"a/b": 1}
    assert flatten({"a": {"b": {"c": 1}, "d": 2}, "e": 3}) == {"a/b/c": 1, "a/d": 2, "e": 3}


def test_dict_param_from_flattened_values():
    spec = [Param("init_cube_pose", dict)]
    out = validate(flatten({"init_cube_pose": {"x": 0, "y": 1}}), spec, SRC)
    assert out["init_cube_pose"] == {"x": 0, "y": 1}


def test_load_yaml_file(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("alpha: 0.1\ninit_cube_pose:\n  y: 0\n")
    assert flatten(load_yaml_file(path)) == {"alpha": 0.1, "init_cube_pose/y": 0}


def test_duplicate_key_rejected(tmp_path):
    path = tmp_path / "dup.yaml"
    path.write_text("alpha: 0.1\nrunning_step: 0.04\nnsteps: 100\nrunning_step: 0.001\n")
    with pytest.raises(ParamError) as info:
        load_yaml_file(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: duplicate key 'running_step'")
    assert "\n" not in msg


def test_duplicate_nested_key_rejected(tmp_path):
    path = tmp_path / "dup.yaml"
    path.write_text("pose:\n  x: 1\n  x: 2\n")
    with pytest.raises(ParamError, match="duplicate key 'x'"):
        load_yaml_file(path)


def test_missing_file(tmp_path):
    path = tmp_path / "nope.yaml"
    with pytest.raises(ParamError) as info:
        load_yaml_file(path)
    assert str(info.value).startswith(str(path))


def test_invalid_yaml_one_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("a: [1, 2\nb: 3\n")
    with pytest.raises(ParamError) as info:
        load_yaml_file(path)
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)
