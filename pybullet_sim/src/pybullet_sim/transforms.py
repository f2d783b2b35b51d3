"""Rotations and frame changes in double precision: quaternions (x, y, z, w) and world-frame states.

PyBullet's own transforms are single precision; the sim's Gazebo services (model and link states in
a reference frame) and its sensors use these instead.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import pybullet as p

from .readings import FrameState


def transpose_rotate(quaternion: Sequence[float], vector: Sequence[float]) -> tuple[float, float, float]:
    """Express a world-frame vector in the frame whose world orientation is `quaternion`."""
    m = p.getMatrixFromQuaternion(quaternion)
    x, y, z = vector
    return (m[0] * x + m[3] * y + m[6] * z, m[1] * x + m[4] * y + m[7] * z, m[2] * x + m[5] * y + m[8] * z)


def cross(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def quaternion_multiply(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float, float]:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def rotate(quaternion: Sequence[float], vector: Sequence[float]) -> tuple[float, float, float]:
    """A vector turned by a unit quaternion (x, y, z, w), in double precision (PyBullet's transforms are float)."""
    axis, w = quaternion[:3], quaternion[3]
    t = tuple(2.0 * c for c in cross(axis, vector))
    turned = cross(axis, t)
    return (vector[0] + w * t[0] + turned[0], vector[1] + w * t[1] + turned[1], vector[2] + w * t[2] + turned[2])


def normalized(quaternion: Sequence[float]) -> tuple[float, ...]:
    """A unit quaternion; all zeros (a default geometry_msgs/Pose) or nearly means no rotation, as in Gazebo.
    Scaled by its largest component first, so that the squares of a finite 1e200 do not overflow."""
    scale = max(abs(q) for q in quaternion)
    if scale < 1e-12:
        return (0.0, 0.0, 0.0, 1.0)
    scaled = [q / scale for q in quaternion]
    norm = math.sqrt(sum(q * q for q in scaled))
    return tuple(q / norm for q in scaled)


def relative_state(state: FrameState, frame: FrameState) -> FrameState:
    """A world-frame state expressed in another frame, as gazebo_ros's get_model_state and get_link_state do:
    the pose relative to the frame, the velocity differences turned into the frame's axes."""
    x, y, z, w = frame.orientation
    inverse = (-x, -y, -z, w)
    position = rotate(inverse, [a - b for a, b in zip(state.position, frame.position, strict=True)])
    linear = rotate(inverse, [a - b for a, b in zip(state.linear_velocity, frame.linear_velocity, strict=True)])
    angular = rotate(inverse, [a - b for a, b in zip(state.angular_velocity, frame.angular_velocity, strict=True)])
    return FrameState(position, quaternion_multiply(inverse, state.orientation), linear, angular)


def absolute_state(state: FrameState, frame: FrameState) -> FrameState:
    """A state given in another frame, in the world frame, as gazebo_ros's set_model_state takes it: the pose
    composed with the frame's, the velocities turned into world axes (the frame's own velocity is not added)."""
    turned = [rotate(frame.orientation, v) for v in (state.position, state.linear_velocity, state.angular_velocity)]
    position = tuple(a + b for a, b in zip(turned[0], frame.position, strict=True))
    return FrameState(position, quaternion_multiply(frame.orientation, normalized(state.orientation)),
                      turned[1], turned[2])
