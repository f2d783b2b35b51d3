"""The cube training's parameters: the tutorial's one_disk_walk_openai_params.yaml keys under /moving_cube/,
validated at start (missing key, wrong type, out of range -> one line naming the key and the file)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Dict

from robot_rl.params import Param, flatten, load_yaml_file, validate

NAMESPACE = "moving_cube"
DEFAULT_CONFIG = Path(__file__).resolve().parents[3] / "config" / "moving_cube_qlearn.yaml"

SPEC = [
    Param("alpha", float, 0.0, 1.0), Param("gamma", float, 0.0, 1.0),
    Param("epsilon", float, 0.0, 1.0), Param("epsilon_discount", float, 0.0, 1.0),
    Param("nepisodes", int, 1), Param("nsteps", int, 1),
    Param("running_step", float, 0.0, low_inclusive=False),
    Param("n_actions", int, 5, 5),
    Param("init_roll_vel", float), Param("roll_speed_fixed_value", float, 0.0, low_inclusive=False),
    Param("roll_speed_increment_value", float, 0.0, low_inclusive=False),
    Param("max_pitch_angle", float, 0.0, low_inclusive=False), Param("max_yaw_angle", float, 0.0, low_inclusive=False),
    Param("init_cube_pose/x", float), Param("init_cube_pose/y", float), Param("init_cube_pose/z", float),
    Param("end_episode_points", float), Param("move_distance_reward_weight", float),
    Param("y_linear_speed_reward_weight", float), Param("y_axis_angle_reward_weight", float),
    Param("reset_settle_time", float, 0.0),
    Param("seed", int, 0),
]


def load_params(path: Path) -> Dict[str, Any]:
    """Validated params from a YAML file holding them under `moving_cube:`."""
    document = load_yaml_file(path)
    return validate_params(document.get(NAMESPACE, {}), str(path))


def validate_params(values: Dict[str, Any], source: str) -> Dict[str, Any]:
    """Validate the /moving_cube/ namespace's params (nested dict as rosparam returns it)."""
    return validate(flatten(values), SPEC, source)


def load_default_params() -> Dict[str, Any]:
    return load_params(DEFAULT_CONFIG)
