"""One check for the sim's parameters: a value of the expected type and range, or a ConfigError naming it.

The robot's sim config (pybullet_sim.config) and the sim node's own private params (pybullet_sim.node)
both read their parameters through `param`, so a mistake reads the same wherever it is made.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar

T = TypeVar("T")
REQUIRED: Any = object()  # `param`'s default when the parameter must be given
_WHAT = {float: "float (a finite number)", int: "int", bool: "bool", str: "a non-empty string", dict: "a dictionary"}


class ConfigError(ValueError):
    """A parameter of the simulator is missing, mistyped or out of range; the message names it."""


def param(params: Mapping[str, Any], key: str, kind: type[T], prefix: str, default: Any = REQUIRED,
          minimum: float | None = None, exclusive_minimum: bool = False, choices: Sequence[Any] = ()) -> T:
    """params[key] as `kind` (float, int, bool, str or dict; an int is taken as a float), else `default`;
    a ConfigError naming the parameter (`prefix` + key, e.g. "~/controllers/" or "~") when it is missing
    without a default, of another type, not finite, an empty string, below `minimum` (at `minimum`
    too when `exclusive_minimum`), or not one of `choices` (when given)."""
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
        raise ConfigError(f"parameter {name} must be {'>' if exclusive_minimum else '>='} {minimum}, got {value!r}")
    if choices and value not in choices:
        raise ConfigError(f"parameter {name} must be one of {', '.join(map(str, choices))}, got {value!r}")
    return value
