"""The in-process backend: the robot in a World of this process, no ROS, the same readings as over ROS.

It makes the same calls as the ROS backend on an in-process World and reads every sensor once per
call, as the sim node publishes them once, so the same seed and actions give the same readings.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from pybullet_sim.config import parse_robot_config
from pybullet_sim.readings import FrameState
from pybullet_sim.sensors import pack_readings

from .base import Backend, Readings, SimStateError, non_finite_problem

if TYPE_CHECKING:
    from ...task import RobotSpec


class DirectBackend(Backend):
    """The robot in an in-process World: no ROS, same readings; `gui` opens PyBullet's window."""

    def __init__(self, urdf_path: Path, sim_config_path: Path, time_step: float = 0.001, seed: int = 0,
                 gui: bool = False):
        from pybullet_sim.world import World  # PyBullet only where it is used
        params = yaml.safe_load(Path(sim_config_path).read_text())
        self.config = parse_robot_config(params, where=str(sim_config_path))
        self._sensor_names = [s.name for s in self.config.sensors]
        self.time_step = time_step
        self.world = World(Path(urdf_path).read_text(), self.config, time_step=time_step, seed=seed, gui=gui,
                           urdf_source=str(urdf_path))
        self._read()  # the sim node publishes every sensor once at start: keep the noise streams aligned

    def _read(self) -> Readings:
        world = self.world
        joints, sensors = world.read_joint_states(), [world.read_sensor(s) for s in self.config.sensors]
        readings = Readings(joints, dict(zip(self._sensor_names, sensors)))
        if not math.isfinite(sum(pack_readings(joints, sensors)[0])):  # the numbers the sim node would send
            problem = non_finite_problem(readings)
            if problem:
                raise SimStateError(problem)
        return readings

    def reset(self, restart_time: bool = False) -> Readings:
        if restart_time:
            self.world.reset_simulation()
        else:
            self.world.reset_world()
        return self._read()

    def set_command(self, controller: str, value: float) -> None:
        self.world.set_command(controller, value)

    def place(self, base: FrameState, joints: Mapping[str, float]) -> None:
        self.world.set_joint_positions(joints)
        self.world.set_model_state(base)

    def kick(self, velocity_change: tuple[float, float]) -> None:
        state = self.world.model_state()
        vx, vy, vz = state.linear_velocity
        self.world.set_model_state(replace(state, linear_velocity=(vx + velocity_change[0], vy + velocity_change[1],
                                                                   vz)))

    def set_attitude_assist(self, stiffness: float, damping: float) -> None:
        self.world.set_attitude_assist(stiffness, damping)

    def step(self, physics_steps: int) -> Readings:
        if not self.world.replay_from_reset(physics_steps):
            self.world.step(physics_steps)
        return self._read()

    def render(self, width: int, height: int) -> np.ndarray:
        return self.world.render(width, height)

    def show(self) -> None:
        self.world.aim_gui_camera()

    def close(self) -> None:
        self.world.close()


def direct_backend(robot: RobotSpec, *, seed: int | None, timeout: float, gui: bool,
                   hint: str | None = None) -> DirectBackend:
    """The factory's "direct": an in-process World of `robot` seeded with `seed`; `gui` opens PyBullet's window
    (`timeout` and `hint` are the ROS backend's)."""
    return DirectBackend(robot.urdf_path, robot.sim_config_path, seed=seed or 0, gui=gui)
