"""The errors the sim's core raises and its callers catch, each naming what is wrong."""
from __future__ import annotations


class ConfigError(ValueError):
    """A parameter of the simulator is missing, mistyped or out of range; the message names it."""


class UrdfError(ValueError):
    """The robot description is missing, not XML, or not a URDF PyBullet can load."""
