"""The effort PID of ros_control's effort_controllers (control_toolbox::Pid), one per controlled joint.

A velocity command is clamped to the joint's velocity limit, a position command to its position
limits, and the effort to its effort limit, as ros_control's joint limits interface does.
"""
from __future__ import annotations

import math

from .config import JointControllerConfig


class EffortPid:
    """One ros_control effort PID (control_toolbox::Pid) on one joint."""

    def __init__(self, config: JointControllerConfig, joint_index: int, effort_limit: float, velocity_limit: float,
                 lower: float, upper: float, continuous: bool):
        self.config = config
        self.joint_index = joint_index
        self.effort_limit = effort_limit
        self.velocity_limit = velocity_limit  # 0 when the URDF gives none
        self.running = True
        self.lower, self.upper = lower, upper
        self.has_limits = not continuous and lower < upper
        self.continuous = continuous
        self.is_position = config.is_position
        gains = config.pid
        self.p, self.i, self.d, self.i_clamp = gains.p, gains.i, gains.d, gains.i_clamp
        self.command = 0.0
        self._integral = 0.0
        self._previous_error = 0.0

    @property
    def memory(self) -> tuple[float, float]:
        """What the PID carries from one step to the next besides its command: (integral, previous error)."""
        return self._integral, self._previous_error

    @memory.setter
    def memory(self, value: tuple[float, float]) -> None:
        self._integral, self._previous_error = value

    def reset(self, position: float) -> None:
        """Controller (re)start: a position controller holds the current position, a velocity one stops."""
        self.command = position if self.is_position else 0.0
        self._integral = 0.0
        self._previous_error = 0.0

    def effort(self, position: float, velocity: float, dt: float) -> float:
        if self.is_position:
            target = min(max(self.command, self.lower), self.upper) if self.has_limits else self.command
            error = target - position
            if self.continuous:
                error = math.remainder(error, 2.0 * math.pi)
            error_dot = -velocity
        else:
            limit = self.velocity_limit
            target = min(max(self.command, -limit), limit) if limit > 0.0 else self.command
            error = target - velocity
            error_dot = (error - self._previous_error) / dt
            self._previous_error = error
        if self.i_clamp > 0.0:
            self._integral = min(max(self._integral + self.i * error * dt, -self.i_clamp), self.i_clamp)
        effort = self.p * error + self._integral + self.d * error_dot
        limit = self.effort_limit
        return -limit if effort < -limit else (limit if effort > limit else effort)
