"""The monoped's leg kinematics, read from its URDF: where the foot and the centre of mass are for given joint
angles, in the base frame, and the crouched start pose that puts the foot under the centre of mass.

Everything comes from the URDF's joint origins and axes, link masses and inertial origins, and the foot's
collision sphere; nothing is copied by hand. Used by the env to place the robot at reset (foot on the ground,
tilted about the foot) and by test_monoped_start.py, which checks it against PyBullet's own kinematics.
"""
from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ElementTree
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tf.transformations import euler_matrix, rotation_matrix

FOOT_LINK = "lowerleg_contactsensor_link"


def _numbers(text: str | None, default: str) -> np.ndarray:
    return np.array([float(v) for v in (text or default).split()])


def _origin(element: ElementTree.Element | None) -> np.ndarray:
    """The 4x4 transform of a URDF <origin> (rpy: fixed axes x, y, z; tf's "sxyz")."""
    origin = None if element is None else element.find("origin")
    xyz = _numbers(None if origin is None else origin.get("xyz"), "0 0 0")
    rpy = _numbers(None if origin is None else origin.get("rpy"), "0 0 0")
    transform = euler_matrix(*rpy, axes="sxyz")
    transform[:3, 3] = xyz
    return transform


@dataclass(frozen=True)
class _Joint:
    name: str
    parent: str
    child: str
    origin: np.ndarray   # 4x4, child frame at zero angle in the parent frame
    axis: np.ndarray     # in the child frame
    movable: bool


class LegKinematics:
    """Forward kinematics of a URDF tree from its root link (the base, at the identity)."""

    def __init__(self, urdf_text: str, foot_link: str = FOOT_LINK):
        root = ElementTree.fromstring(urdf_text)
        self.masses: dict[str, float] = {}
        self.inertial_origins: dict[str, np.ndarray] = {}
        for link in root.findall("link"):
            inertial = link.find("inertial")
            if inertial is not None:
                mass = inertial.find("mass")
                self.masses[link.get("name", "")] = float(mass.get("value", "0")) if mass is not None else 0.0
                self.inertial_origins[link.get("name", "")] = _origin(inertial)[:3, 3]
        self.joints = [_Joint(j.get("name", ""), j.find("parent").get("link", ""),  # type: ignore[union-attr]
                              j.find("child").get("link", ""), _origin(j),  # type: ignore[union-attr]
                              _numbers(j.find("axis").get("xyz") if j.find("axis") is not None else None,  # type: ignore[union-attr]
                                       "1 0 0"),
                              j.get("type") in ("revolute", "continuous"))
                       for j in root.findall("joint")]
        children = {j.child for j in self.joints}
        self.root = next(link.get("name", "") for link in root.findall("link") if link.get("name") not in children)
        self.foot_link = foot_link
        foot = next(link for link in root.findall("link") if link.get("name") == foot_link)
        sphere = foot.find("collision/geometry/sphere")
        if sphere is None:
            raise ValueError(f"link {foot_link!r} has no collision sphere: the foot's radius is unknown")
        self.foot_radius = float(sphere.get("radius", "0"))

    def link_frames(self, angles: Mapping[str, float]) -> dict[str, np.ndarray]:
        """Every link's 4x4 frame in the root (base) frame; joints not named are at 0."""
        frames = {self.root: np.eye(4)}
        pending = list(self.joints)
        while pending:
            joint = next(j for j in pending if j.parent in frames)
            pending.remove(joint)
            motion = rotation_matrix(angles.get(joint.name, 0.0), joint.axis) if joint.movable else np.eye(4)
            frames[joint.child] = frames[joint.parent] @ joint.origin @ motion
        return frames

    def foot(self, angles: Mapping[str, float]) -> np.ndarray:
        """The foot sphere's centre in the base frame (m)."""
        return self.link_frames(angles)[self.foot_link][:3, 3]

    def centre_of_mass(self, angles: Mapping[str, float]) -> np.ndarray:
        """The whole robot's centre of mass in the base frame (m)."""
        frames = self.link_frames(angles)
        total = sum(self.masses.values())
        return sum((mass * (frames[link] @ np.append(self.inertial_origins[link], 1.0))[:3]
                    for link, mass in self.masses.items()), np.zeros(3)) / total

    def balanced_hip_angle(self, hip: str, knee: str, knee_angle: float, bracket: Sequence[float]) -> float:
        """The `hip` angle in `bracket` (rad) that puts the foot under the centre of mass (same base x) with the
        knee at `knee_angle`, the base upright: bisection on the x offset of the foot from the CoM."""
        def offset(angle: float) -> float:
            angles = {hip: angle, knee: knee_angle}
            return float(self.foot(angles)[0] - self.centre_of_mass(angles)[0])
        low, high = bracket
        if offset(low) * offset(high) > 0.0:
            raise ValueError(f"no {hip} angle in {tuple(bracket)} puts the foot under the centre of mass")
        for _ in range(60):
            middle = 0.5 * (low + high)
            if offset(low) * offset(middle) <= 0.0:
                high = middle
            else:
                low = middle
        return 0.5 * (low + high)


@functools.cache
def leg_kinematics(urdf_path: Path) -> LegKinematics:
    """The kinematics of the URDF at `urdf_path` (read once)."""
    return LegKinematics(urdf_path.read_text(encoding="utf-8"))


def tilt_rotation(angle: float, direction: float) -> np.ndarray:
    """3x3 rotation by `angle` (rad) about the horizontal axis that leans the robot's top towards the
    world heading `direction` (rad from +x): the base's z axis then points along that heading, tilted `angle`."""
    axis = (-math.sin(direction), math.cos(direction), 0.0)  # z x heading: a positive turn leans towards it
    return rotation_matrix(angle, axis)[:3, :3]
