"""The rendered scene: what a World's frames show, drawn in a PyBullet client of its own.

The scene is a second PyBullet connection (DIRECT) that holds the same URDF and ground plane as the World,
plus what only the pictures need: height poles (`camera.poles`), shadows, each contact sensor's link in
`camera.contact_color` while it touches something, and a disc on the ground under it
(`camera.ground_marks`). It is never stepped: before each frame it takes the
robot's base pose and joint positions from the World, so rendering changes nothing in the World's physics
client (no body added, no colour changed, no saved state touched) and costs nothing until the first frame.
The camera's aim (`camera_target`) follows the base, its x and y only, or stays fixed (`camera.follow`).
No ROS here.
"""
from __future__ import annotations

import os
import tempfile
from collections.abc import Collection, Sequence

import numpy as np
import pybullet as p

from .config import CameraConfig, RobotConfig
from .errors import UrdfError

__all__ = ["MAX_IMAGE_SIZE", "Scene", "camera_target", "check_image_size"]

MAX_IMAGE_SIZE = 4096  # pixels per side of a rendered image
POLE_WIDTH = 0.03  # m, the light pole's side; its dark bands are a little wider, so that they show on it
POLE_LIGHT = (0.95, 0.95, 0.9, 1.0)
POLE_DARK = (0.1, 0.1, 0.1, 1.0)
MARK_RADIUS = 0.03  # m, a ground mark's disc
MARK_COLOUR = (0.25, 0.25, 0.3, 1.0)


def check_image_size(width: int, height: int) -> None:
    """ValueError unless width and height are whole pixels from 1 to MAX_IMAGE_SIZE."""
    if not all(isinstance(v, int) and 1 <= v <= MAX_IMAGE_SIZE for v in (width, height)):
        raise ValueError(f"image size must be whole pixels from 1 to {MAX_IMAGE_SIZE} a side, got {width!r} x "
                         f"{height!r}")


def camera_target(camera: CameraConfig, base_position: Sequence[float],
                  spawn_position: Sequence[float]) -> tuple[float, float, float]:
    """The point the camera looks at (see CameraConfig.follow), from the base's position (its centre of mass)."""
    x, y, z = base_position
    if camera.follow == "base":
        return (x, y, z + camera.z_offset)
    if camera.follow == "horizontal":
        return (x, y, camera.target_height)
    return (spawn_position[0], spawn_position[1], camera.target_height)


class Scene:
    """The robot's URDF on a ground plane with the camera config's poles, in a PyBullet client of its own."""

    def __init__(self, urdf_text: str, config: RobotConfig, contact_links: Collection[int]):
        self.config = config
        self._cid = p.connect(p.DIRECT)
        if self._cid < 0:
            raise RuntimeError("PyBullet could not connect a client for rendering")
        try:
            self._build(urdf_text, contact_links)
        except Exception:
            self.close()
            raise

    def _build(self, urdf_text: str, contact_links: Collection[int]) -> None:
        cid = self._cid
        p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid), physicsClientId=cid)
        with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as handle:
            handle.write(urdf_text)
        try:  # the World's flags: the same inertial frames, so the base's pose means the same here
            self._body = p.loadURDF(handle.name, self.config.spawn_xyz, flags=p.URDF_USE_INERTIA_FROM_FILE,
                                    physicsClientId=cid)
        except p.error as error:
            raise UrdfError(f"the URDF could not be loaded for rendering ({error})") from None
        finally:
            os.unlink(handle.name)
        # each contact sensor link's own colour, given back when it stops touching
        colours = {shape[1]: tuple(shape[7]) for shape in p.getVisualShapeData(self._body, physicsClientId=cid)}
        self._own_colours = {link: colours[link] for link in contact_links if link in colours}
        self._marked: set[int] = set()
        self._add_poles()
        self._marks: dict[int, int] = {}  # contact sensor link -> its ground mark's body
        if self.config.camera.ground_marks:
            disc = p.createVisualShape(p.GEOM_CYLINDER, radius=MARK_RADIUS, length=0.002, rgbaColor=MARK_COLOUR,
                                       physicsClientId=cid)
            self._marks = {link: p.createMultiBody(0, -1, disc, (0.0, 0.0, 0.001), physicsClientId=cid)
                           for link in sorted(contact_links)}

    def _add_poles(self) -> None:
        poles, cid = self.config.camera.poles, self._cid
        if not poles.xs:
            return
        light = p.createVisualShape(p.GEOM_BOX, halfExtents=(POLE_WIDTH / 2, POLE_WIDTH / 2, poles.height / 2),
                                    rgbaColor=POLE_LIGHT, physicsClientId=cid)
        p.createMultiBody(0, -1, light, batchPositions=[(x, poles.y, poles.height / 2) for x in poles.xs],
                          physicsClientId=cid)
        dark_bands = [(x, poles.y, (2 * k + 0.5) * poles.band) for x in poles.xs
                      for k in range(int(poles.height / poles.band + 1e-9) // 2)]
        if dark_bands:  # every other band from the ground up is dark: the first 0 to `band` m
            dark = p.createVisualShape(p.GEOM_BOX, halfExtents=(POLE_WIDTH * 0.6, POLE_WIDTH * 0.6, poles.band / 2),
                                       rgbaColor=POLE_DARK, physicsClientId=cid)
            p.createMultiBody(0, -1, dark, batchPositions=dark_bands, physicsClientId=cid)

    def render(self, width: int, height: int, base_pose: tuple[Sequence[float], Sequence[float]],
               joint_positions: Sequence[tuple[int, float]], touching: Collection[int]) -> np.ndarray:
        """An RGB image (height x width x 3, uint8) of the robot with its base at `base_pose` (centre of mass,
        quaternion), joints at `joint_positions` ((PyBullet joint index, position) pairs), and the contact
        sensor links `touching` marked; drawn by PyBullet's TinyRenderer, which needs no display."""
        check_image_size(width, height)
        cid, body, camera = self._cid, self._body, self.config.camera
        p.resetBasePositionAndOrientation(body, base_pose[0], base_pose[1], physicsClientId=cid)
        for index, position in joint_positions:
            p.resetJointState(body, index, position, physicsClientId=cid)
        for link, mark in self._marks.items():
            x, y, _ = p.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=cid)[4]
            p.resetBasePositionAndOrientation(mark, (x, y, 0.001), (0.0, 0.0, 0.0, 1.0), physicsClientId=cid)
        if camera.contact_color:
            marked = {link for link in touching if link in self._own_colours}
            for link in marked ^ self._marked:
                colour = camera.contact_color if link in marked else self._own_colours[link]
                p.changeVisualShape(body, link, rgbaColor=colour, physicsClientId=cid)
            self._marked = marked
        target = camera_target(camera, base_pose[0], self.config.spawn_xyz)
        view = p.computeViewMatrixFromYawPitchRoll(target, camera.distance, camera.yaw, camera.pitch, 0.0, 2,
                                                   physicsClientId=cid)
        projection = p.computeProjectionMatrixFOV(camera.fov, width / height, 0.01, 100.0, physicsClientId=cid)
        rgba = p.getCameraImage(width, height, view, projection, renderer=p.ER_TINY_RENDERER,
                                shadow=int(camera.shadows), lightDirection=camera.light_direction,
                                physicsClientId=cid)[2]
        return np.ascontiguousarray(np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3])

    def close(self) -> None:
        if self._cid >= 0:
            p.disconnect(self._cid)
            self._cid = -1
