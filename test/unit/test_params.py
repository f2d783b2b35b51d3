"""Unit tests for robot_rl.params: typed params dataclasses and the YAML loader (no ROS needed)."""
from dataclasses import FrozenInstanceError, dataclass

import pytest

from robot_rl import ParamError, Params, Point, load_yaml_file, param

SRC = "/ws/config/hopper.yaml"


@dataclass(frozen=True, kw_only=True)
class Example(Params):
    alpha: float = param(low=0.0, high=1.0, low_open=True)
    nepisodes: int = param(low=1)
    running_step: float = param(low=0.0, low_open=True)
    init_cube_pose: Point
    use_gui: bool
    robot: str = param(choices=("hopper", "cube"))
    seed: int = param(low=0, default=0)


GOOD = {"alpha": 0.1, "nepisodes": 500, "running_step": 0.04, "init_cube_pose": {"x": 0, "y": 1, "z": 2.5},
        "use_gui": False, "robot": "hopper"}


def error(values):
    with pytest.raises(ParamError) as info:
        Example.from_mapping(values, SRC)
    msg = str(info.value)
    assert msg.startswith(SRC + ": ")
    assert "\n" not in msg
    return msg


def test_valid_values_become_typed_attributes():
    p = Example.from_mapping(GOOD, SRC)
    assert (p.alpha, p.nepisodes, p.robot, p.seed) == (0.1, 500, "hopper", 0)
    assert p.init_cube_pose == Point(x=0.0, y=1.0, z=2.5) and type(p.init_cube_pose.x) is float
    assert type(p.nepisodes) is int
    with pytest.raises(FrozenInstanceError):
        p.alpha = 0.2


def test_round_trip_and_unknown_keys_ignored():
    p = Example.from_mapping({**GOOD, "use_sim_time": True, "pos_step": 0.016}, SRC)
    assert Example.from_mapping(p.to_mapping(), SRC) == p
    assert p.to_mapping()["init_cube_pose"] == {"x": 0.0, "y": 1.0, "z": 2.5}


def test_with_changes_validates_again():
    p = Example.from_mapping(GOOD, SRC)
    assert p.with_changes("~nepisodes", nepisodes=5).nepisodes == 5
    with pytest.raises(ParamError, match="^~nepisodes: parameter 'nepisodes' = 0 out of range"):
        p.with_changes("~nepisodes", nepisodes=0)


def test_require_saved_accepts_the_same_params_and_names_each_key_that_differs():
    """A resume's check of a checkpoint's agent params (the SB3, RLlib and bc_dagger trainers call it)."""
    p = Example.from_mapping(GOOD, SRC)
    p.require_saved({**GOOD, "seed": 0})  # a default filled in reads the same
    with pytest.raises(ValueError, match=r"^its agent params differ from this run's \(alpha 0.2 there, 0.1 here, "
                                         r"nepisodes 7 there, 500 here\): resume with the params the run began with$"):
        p.require_saved({**GOOD, "alpha": 0.2, "nepisodes": 7})
    with pytest.raises(ValueError, match=r"^agent_params: parameter 'alpha' = 2.0 out of range"):
        p.require_saved({**GOOD, "alpha": 2.0})


@pytest.mark.parametrize("key", ["running_step", "use_gui"])
def test_missing(key):
    values = dict(GOOD)
    del values[key]
    assert error(values) == f"{SRC}: missing parameter '{key}'"


def test_missing_nested_and_defaults():
    assert error({**GOOD, "init_cube_pose": {"x": 0, "y": 1}}) == f"{SRC}: missing parameter 'init_cube_pose/z'"
    assert "'init_cube_pose' must be a mapping" in error({**GOOD, "init_cube_pose": 3})
    assert Example.from_mapping({**GOOD, "seed": 7}, SRC).seed == 7


@pytest.mark.parametrize("key, bad, expected", [
    ("alpha", "0.1", "float"),
    ("nepisodes", True, "int"),
    ("nepisodes", 1.5, "int"),
    ("nepisodes", 500.0, "int"),
    ("alpha", True, "float"),
    ("use_gui", 1, "bool"),
    ("robot", 3, "str"),
])
def test_wrong_type(key, bad, expected):
    msg = error({**GOOD, key: bad})
    assert f"'{key}'" in msg
    assert f"expected {expected}" in msg
    assert repr(bad) in msg and type(bad).__name__ in msg


@pytest.mark.parametrize("key, bad", [("alpha", 0.0), ("alpha", 1.5), ("nepisodes", 0),
                                      ("running_step", -0.1), ("seed", -1)])
def test_out_of_range(key, bad):
    msg = error({**GOOD, key: bad})
    assert f"'{key}'" in msg and repr(bad) in msg and "range" in msg


def test_nan_and_unknown_choice_rejected():
    assert "NaN" in error({**GOOD, "alpha": float("nan")})
    assert "is not one of hopper, cube" in error({**GOOD, "robot": "drone"})


def test_load_yaml_file(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("alpha: 0.1\ninit_cube_pose:\n  y: 0\n")
    assert load_yaml_file(path) == {"alpha": 0.1, "init_cube_pose": {"y": 0}}


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


@pytest.mark.parametrize("value", ['!radians __import__("os").system("touch {marker}") or 0.1',
                                   "!degrees 90", "rad(1)"])
def test_rosparams_yaml_tags_are_refused_and_never_evaluated(tmp_path, value):
    """rosparam (imported here as roslaunch and the nodes import it) registers !radians on yaml.SafeLoader and
    evaluates it with eval(); a config is data: the tag is refused and nothing runs."""
    import rosparam  # noqa: F401 (registers its tags on yaml.SafeLoader)
    marker = tmp_path / "marker"
    path = tmp_path / "config.yaml"
    path.write_text(f"alpha: {value.format(marker=marker)}\n")
    if value.startswith("!"):
        with pytest.raises(ParamError, match=f"{path}: invalid YAML: could not determine a constructor for the tag"):
            load_yaml_file(path)
    else:
        assert load_yaml_file(path) == {"alpha": "rad(1)"}  # a plain string, as YAML reads it
    assert not marker.exists()


@pytest.mark.parametrize("text, value", [("12", 12), ("0.5", 0.5), ("true", True), ("2147483648", 2147483648),
                                         ("abc", "abc"), ("1e21", "1e21"), ("!radians 1", "!radians 1"), ("", "")])
def test_launch_argument_text_is_typed_as_yaml_types_a_scalar_and_never_evaluated(text, value):
    from robot_rl import parse_scalar
    assert parse_scalar(text) == value and type(parse_scalar(text)) is type(value)


@pytest.mark.parametrize("key, value", [("seed", 2**31), ("seed", -1), ("nepisodes", 10**10), ("nsteps", 10**10),
                                        ("running_step", 1e308)])
def test_absurd_but_finite_task_params_are_refused(key, value):
    from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
    with pytest.raises(ParamError, match=f"parameter '{key}' = .* out of range"):
        ONE_DISK_WALK.default_params().with_changes("test", **{key: value})


@dataclass(frozen=True, kw_only=True)
class Tolerant(Example):
    TOLERATED_KEYS = ("pos_step",)


@pytest.mark.parametrize("extra, named", [
    ({"alpah": 0.2}, "'alpah'"),
    ({"init_cube_pose": {"x": 0, "y": 1, "z": 2.5, "w": 1}}, "'init_cube_pose/w'"),
    ({"alpah": 0.2, "gama": 0.9}, "'alpah' (and 1 more)"),
], ids=["top_level", "nested", "two"])
def test_a_config_files_unknown_key_is_refused_naming_it_and_the_file(extra, named):
    """strict (a config file): a typo is refused, not silently a default; the parameter server's other keys are
    not (strict=False), and a type's TOLERATED_KEYS (the tutorials' unused keys) never are."""
    with pytest.raises(ParamError) as info:
        Example.from_mapping({**GOOD, **extra}, SRC, strict=True)
    assert str(info.value).startswith(f"{SRC}: unknown parameter {named} (known: alpha, nepisodes,")
    assert "\n" not in str(info.value)
    Example.from_mapping({**GOOD, **extra}, SRC)
    assert Tolerant.from_mapping({**GOOD, "pos_step": 0.016}, SRC, strict=True).alpha == 0.1


def test_every_shipped_config_loads_strictly_the_cubes_with_the_tutorials_unused_keys():
    from hopper_training import TASKS as HOPPER_TASKS
    from moving_cube_training import TASKS as CUBE_TASKS
    for task in (*HOPPER_TASKS, *CUBE_TASKS):
        task.load_params(task.config_path)
    cube = CUBE_TASKS[0]
    assert {"pos_step", "number_splits", "max_distance"} <= set(load_yaml_file(cube.config_path)["moving_cube"])
