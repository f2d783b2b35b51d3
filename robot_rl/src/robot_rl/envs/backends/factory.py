"""The one place that maps a backend's name ("ros", "direct") to a backend.

Each name is a "module:attr" reference to a function (robot, *, seed, timeout, gui, hint) -> Backend, imported
when asked for, so that a process that never asks for "ros" never imports rospy.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from .base import Backend

if TYPE_CHECKING:
    from ...task import RobotSpec

BACKENDS: dict[str, str] = {
    "ros": "robot_rl.envs.backends.ros:ros_backend",            # a sim node must be running
    "direct": "robot_rl.envs.backends.direct:direct_backend",   # an in-process World
}
ROS = "ros"


def check_backend_name(kind: Any) -> None:
    """ValueError unless `kind` names a backend."""
    if kind not in BACKENDS:
        raise ValueError(f"backend must be 'ros' or 'direct', got {kind!r}")


def over_ros(kind: str) -> bool:
    """Whether the backend named `kind` reaches its robot over ROS (a master and a sim node)."""
    return kind == ROS


def make_backend(kind: Any, robot: RobotSpec, seed: int | None = None, timeout: float = 10.0,
                 gui: bool = False, hint: str | None = None) -> Backend:
    """`kind` "ros" (a sim node must be running; `hint`: what to check when it does not answer), "direct" (an
    in-process World of `robot` seeded with `seed`; `gui` opens PyBullet's window), or a Backend, returned as
    it is."""
    if isinstance(kind, Backend):
        return kind
    check_backend_name(kind)
    module, _, attr = BACKENDS[kind].partition(":")
    make: Callable[..., Backend] = getattr(importlib.import_module(module), attr)
    return make(robot, seed=seed, timeout=timeout, gui=gui, hint=hint)
