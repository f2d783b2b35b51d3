"""The Backend protocol every backend keeps, the Readings it returns, and the check that they are finite.

Every backend exposes the same three calls, each returning the same `Readings`:
`reset(restart_time)`, `set_command(controller, value)` + `step(physics_steps)`; and the same
`render(width, height)`, an RGB frame from the sim's camera that follows the robot, `place(base,
joints)`, which puts the robot in a start pose after a reset (Gazebo's set_model_configuration and
set_model_state), `kick(velocity_change)`, a push of the base (get_model_state and set_model_state), and
`set_attitude_assist(stiffness, damping)`, the sim's torque that pulls the base upright (a curriculum's help).
Every backend refuses readings that are not finite numbers (a state that blew up, whatever the path): the call
raises, naming the first such reading, instead of handing NaN to the task.
The backends: robot_rl.envs.backends.direct (in-process) and .ros (over ROS); .factory makes one by name.
"""
from __future__ import annotations

import abc
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from pybullet_sim.config import RobotConfig
from pybullet_sim.readings import ContactReading, FrameState, ImuReading, JointStateReading, OdometryReading

SensorReading = OdometryReading | ImuReading | ContactReading
R = TypeVar("R", OdometryReading, ImuReading, ContactReading)

@dataclass(frozen=True)
class Readings:
    """One snapshot of every sensor of the robot, all stamped at the same sim time."""

    joints: JointStateReading
    sensors: Mapping[str, SensorReading]  # sensor name (as in config/<robot>_sim.yaml) -> reading

    @property
    def stamp(self) -> float:
        return self.joints.stamp

    def odometry(self, name: str) -> OdometryReading:
        return self._sensor(name, OdometryReading)

    def imu(self, name: str) -> ImuReading:
        return self._sensor(name, ImuReading)

    def contact(self, name: str) -> ContactReading:
        return self._sensor(name, ContactReading)

    def _sensor(self, name: str, kind: type[R]) -> R:
        reading = self.sensors.get(name)
        if not isinstance(reading, kind):
            raise KeyError(f"the robot has no {kind.__name__[:-len('Reading')].lower()} sensor {name!r} "
                           f"(its sensors: {', '.join(sorted(self.sensors)) or 'none'})")
        return reading


class SimStateError(RuntimeError):
    """The sim's readings are not finite numbers: its state blew up. The message names the reading."""


def _first_non_finite(value: Any, where: str) -> str:
    """The name of the first number in `value` (a reading, or a tuple or dataclass in one) that is not finite, or ""."""
    if isinstance(value, float):
        return "" if math.isfinite(value) else f"{where} = {value!r}"
    if isinstance(value, tuple):
        return next((found for i, item in enumerate(value) if (found := _first_non_finite(item, f"{where}[{i}]"))), "")
    if dataclasses.is_dataclass(value):
        return next((found for f in dataclasses.fields(value)
                     if (found := _first_non_finite(getattr(value, f.name), f"{where}.{f.name}"))), "")
    return ""


def non_finite_problem(readings: Readings) -> str:
    """Why `readings` cannot go to a task ("" if every number in them is finite): the first reading that is NaN or
    infinite, and what to check."""
    found = _first_non_finite(readings.joints, "joint_states") or next(
        (found for name, reading in readings.sensors.items() if (found := _first_non_finite(reading, name))), "")
    if not found:
        return ""
    return (f"the sim's state is no longer finite at sim time {readings.stamp:.6f} s: {found}; the physics blew up "
            f"(check what else sets the robot's state or the physics through the sim's services), so the episode "
            f"cannot go on: restart the sim")


class Backend(abc.ABC):
    """A robot and its sim, seen as readings and controller commands."""

    config: RobotConfig
    time_step: float

    @abc.abstractmethod
    def reset(self, restart_time: bool = False) -> Readings:
        """Robot back to its spawn pose, controllers restarted (Gazebo's reset_world); with
        restart_time also sim time and the sensor-noise generator (reset_simulation)."""

    @abc.abstractmethod
    def set_command(self, controller: str, value: float) -> None:
        """Command a controller; it takes effect from the next step."""

    @abc.abstractmethod
    def step(self, physics_steps: int) -> Readings:
        """Advance exactly `physics_steps` physics steps and return the readings at the new time."""

    @abc.abstractmethod
    def render(self, width: int, height: int) -> np.ndarray:
        """An RGB image (height x width x 3, uint8) of the robot from the sim's camera that follows it."""

    def place(self, base: FrameState, joints: Mapping[str, float]) -> None:
        """Set the named joints' positions at rest (Gazebo's set_model_configuration), then the base frame's
        pose and twist in the world frame (set_model_state); the readings change with the next step."""
        raise NotImplementedError(f"{type(self).__name__} cannot place the robot")

    def kick(self, velocity_change: tuple[float, float]) -> None:
        """Add a horizontal velocity (m/s, world x and y) to the robot's base, its pose, its spin and its joints as
        they are (a push, robot_rl.envs.pushes); the readings change with the next step."""
        raise NotImplementedError(f"{type(self).__name__} cannot push the robot")

    def set_attitude_assist(self, stiffness: float, damping: float) -> None:
        """Pull the base upright from the next step on (pybullet_sim's attitude assist: N m/rad of tilt, N m s/rad of
        horizontal spin; 0, 0: off); resets keep it."""
        raise NotImplementedError(f"{type(self).__name__} cannot assist the robot's attitude")

    def show(self) -> None:  # noqa: B027 (optional: over ROS the sim node's window or rviz shows the robot)
        """Bring the human view of the robot up to date."""

    def close(self) -> None:  # noqa: B027 (optional: a backend without resources keeps this)
        """Release the backend's resources."""
