"""One check for the sim's parameters: a value of the expected type and range, or a ConfigError naming it;
and the bounds of the state values the sim accepts from outside, stated once.

The robot's sim config (pybullet_sim.config) and the sim node's own private params (pybullet_sim.ros.node)
both read their parameters through `param`, so a mistake reads the same wherever it is made.

Gazebo takes any finite number for a pose, a twist, gravity or a time step; PyBullet does not simulate
all of them: a position of 1e30 m loses every digit below 1e14 m, a speed beyond the World's velocity
clamp is cut to it without a word, gravity of 1e5 m/s^2 pushes the robot through the ground, and a time
step of 1e30 s makes a sim time no ROS message can carry. So a request beyond these bounds is refused,
naming the field and the bound, and nothing changes (pybullet_sim/README.md, "Bad input"). The robot's sim
config is held to bounds of the same kind: its spawn pose, PID gains and sensor noise.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar

from .errors import ConfigError

T = TypeVar("T")
REQUIRED: Any = object()  # `param`'s default when the parameter must be given
MAX_POSITION = 1.0e6  # m from the origin along each axis: doubles keep 1e-10 m there
MAX_SPEED = 1000.0  # m/s and rad/s per axis: the World's velocity clamp (Bullet's maxJointVelocity) is at least this
MAX_GRAVITY = 1000.0  # m/s^2 per axis (about 100 g): the robots still rest on the ground at the 1 ms step
MAX_TIME_STEP = 1.0  # s: a physics step longer than this is no simulation; sim time stays within ROS's 2**32 s
MAX_WAIT = 3600.0  # s: the longest timeout a param may give (Python's waits refuse much longer ones)
MAX_SPAWN_ANGLE = 2 * math.pi  # rad: the spawn's roll, pitch, yaw within a turn either way (90 there: degrees?)
MAX_GAIN = 1.0e6  # a PID gain p, i or d, either sign: 1e5 x the configs' largest (10); effort is clamped anyway
MAX_RATE = 1.0e6  # Hz of sim time: a publish_rate or update_rate above one per shortest physics step (1e-6 s)
MAX_CAMERA_ANGLE = 360.0  # degrees: the camera's yaw and pitch within a turn either way
MAX_SCENE_SIZE = 100.0  # m: a height pole or a band of one in the rendered scene
MAX_NOISE = 1.0  # a sensor's gaussian_noise (std dev in m, rad, m/s, rad/s, m/s^2): beyond it a reading hides the state
_WHAT = {float: "float (a finite number)", int: "int", bool: "bool", str: "a non-empty string", dict: "a dictionary"}


def param(params: Mapping[str, Any], key: str, kind: type[T], prefix: str, default: Any = REQUIRED,
          minimum: float | None = None, exclusive_minimum: bool = False, maximum: float | None = None,
          choices: Sequence[Any] = ()) -> T:
    """params[key] as `kind` (float, int, bool, str or dict; an int is taken as a float), else `default`;
    a ConfigError naming the parameter (`prefix` + key, e.g. "~/controllers/" or "~") when it is missing
    without a default, of another type, not finite, an empty string, below `minimum` (at `minimum`
    too when `exclusive_minimum`), above `maximum`, or not one of `choices` (when given)."""
    name = prefix + key
    if key not in params:
        if default is REQUIRED:
            raise ConfigError(f"missing parameter {name}")
        value = default
    else:
        value = params[key]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if (not isinstance(value, kind) or (kind is not bool and isinstance(value, bool))
            or (isinstance(value, float) and not math.isfinite(value)) or (kind is str and not value)):
        raise ConfigError(f"parameter {name} must be {_WHAT[kind]}, got {value!r}")
    if minimum is not None and (value < minimum or (exclusive_minimum and value == minimum)):  # type: ignore[operator]
        raise ConfigError(f"parameter {name} must be {'>' if exclusive_minimum else '>='} {minimum:g}, got {value!r}")
    if maximum is not None and value > maximum:  # type: ignore[operator]
        raise ConfigError(f"parameter {name} must be <= {maximum:g}, got {value!r}")
    if choices and value not in choices:
        raise ConfigError(f"parameter {name} must be one of {', '.join(map(str, choices))}, got {value!r}")
    return value


def out_of_bounds(name: str, values: Sequence[float], bound: float, unit: str) -> str:
    """Why `values` (the x, y, z of field `name`) are refused: one is not finite or beyond +-`bound`; "" if none is."""
    for axis, value in zip("xyz", values, strict=True):
        if not (math.isfinite(value) and -bound <= value <= bound):
            return f"{name}.{axis} must be a finite number within +-{bound:g} {unit}, got {value!r}"
    return ""


def frame_state_problem(position: Sequence[float], orientation: Sequence[float], linear_velocity: Sequence[float],
                        angular_velocity: Sequence[float]) -> str:
    """Why a pose and twist (gazebo_msgs/ModelState's, world frame) cannot be set ("" if they can). Any finite
    orientation is taken, as Gazebo takes it: normalised, all zeros meaning no rotation."""
    if not all(math.isfinite(q) for q in orientation):
        return f"pose.orientation must be finite numbers, got {tuple(orientation)!r}"
    return (out_of_bounds("pose.position", position, MAX_POSITION, "m")
            or out_of_bounds("twist.linear", linear_velocity, MAX_SPEED, "m/s")
            or out_of_bounds("twist.angular", angular_velocity, MAX_SPEED, "rad/s"))
