"""The robot description (URDF) as the sim reads it: the robot's name and its joints with their limits.

PyBullet loads the URDF itself; this parser only checks that the text is a URDF before PyBullet sees
it (so errors name their source) and gives the joints' types and <limit>s to code that does not load
physics, such as a task env that keeps its commands inside the limits.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass

from .errors import UrdfError


@dataclass(frozen=True)
class UrdfJoint:
    """A joint and its <limit> (rad or m, rad/s or m/s, N m or N; 0 when not given, NaN when not a number)."""

    name: str
    type: str
    lower: float = 0.0
    upper: float = 0.0
    velocity: float = 0.0
    effort: float = 0.0


def _limit(element: ElementTree.Element, attribute: str) -> float:
    """A <limit> attribute of a joint element: 0 when absent, NaN when not a number (PyBullet judges the URDF)."""
    limit = element.find("limit")
    text = None if limit is None else limit.get(attribute)
    if text is None:
        return 0.0
    try:
        return float(text)
    except ValueError:
        return math.nan


def parse_urdf_joints(urdf_text: str, source: str) -> tuple[str, dict[str, UrdfJoint]]:
    """Return the robot name and its joints by name; raise UrdfError naming `source` if it is not a URDF."""
    if not urdf_text or not urdf_text.strip():
        raise UrdfError(f"{source} is empty")
    try:
        root = ElementTree.fromstring(urdf_text)
    except ElementTree.ParseError as error:
        raise UrdfError(f"{source} is not valid XML: {error}") from None
    if root.tag != "robot" or not root.get("name"):
        raise UrdfError(f"{source} is not a URDF: the root element must be <robot name=...>, got <{root.tag}>")
    if root.find("link") is None:
        raise UrdfError(f"{source} is not a URDF: it has no <link>")
    joints = {}
    for element in root.findall("joint"):
        name, kind = element.get("name"), element.get("type")
        if not name or not kind:
            raise UrdfError(f"{source} is not a URDF: a <joint> has no name or no type")
        joints[name] = UrdfJoint(name, kind, *(_limit(element, a)
                                               for a in ("lower", "upper", "velocity", "effort")))
    return str(root.get("name")), joints
