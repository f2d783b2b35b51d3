"""The hopper training's parameters: seed 001's qlearn_params.yaml keys at the root namespace,
validated at start (missing key, wrong type, out of range -> one line naming the key and the file)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Dict

from robot_rl.params import Param, ParamError, flatten, load_yaml_file, validate

DEFAULT_CONFIG = Path(__file__).resolve().parents[3] / "config" / "hopper_qlearn.yaml"

SPEC = [
    Param("alpha", float, 0.0, 1.0), Param("gamma", float, 0.0, 1.0),
    Param("epsilon", float, 0.0, 1.0), Param("epsilon_discount", float, 0.0, 1.0),
    Param("nepisodes", int, 1), Param("nsteps", int, 1), Param("seed", int, 0),
    Param("desired_pose/x", float), Param("desired_pose/y", float), Param("desired_pose/z", float),
    Param("desired_force", float, 0.0), Param("desired_yaw", float),
    Param("max_height", float), Param("min_height", float), Param("max_incl", float, 0.0, low_inclusive=False),
    Param("running_step", float, 0.0, low_inclusive=False),
    Param("joint_increment_value", float, 0.0, low_inclusive=False),
    Param("done_reward", float), Param("alive_reward", float),
    *(Param(f"weight_r{i}", float) for i in range(1, 6)),
]


def validate_params(values: Dict[str, Any], source: str) -> Dict[str, Any]:
    """Validate the hopper's params (a nested dict as rosparam or YAML gives it)."""
    params = validate(flatten(values), SPEC, source)
    if not params["min_height"] < params["max_height"]:
        raise ParamError(f"{source}: parameter 'min_height' ({params['min_height']}) must be below "
                         f"'max_height' ({params['max_height']})")
    return params


def load_params(path: Path) -> Dict[str, Any]:
    return validate_params(load_yaml_file(path), str(path))


def load_default_params() -> Dict[str, Any]:
    return load_params(DEFAULT_CONFIG)
