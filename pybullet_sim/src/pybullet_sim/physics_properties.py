"""Gazebo's physics properties (gazebo_msgs/SetPhysicsProperties) checked and mapped onto a World. No ROS here.

Gazebo's set_physics_properties sets gravity, the physics step (time_step), the real-time update rate
(max_update_rate: steps per wall second, 0 = as fast as possible) and the ODE solver (ode_config). Here:

- gravity: World.set_gravity, kept across resets as in Gazebo; at most MAX_GRAVITY per axis (validation).
- time_step: World.set_time_step; sim time stays continuous; at most MAX_TIME_STEP (validation).
- max_update_rate: the real-time factor, max_update_rate * time_step (0 = as fast as possible).
- ode_config.sor_pgs_iters, sor_pgs_rms_error_tol, erp, cfm: PyBullet's solver iterations, residual
  threshold, erp and global cfm (World.set_solver; PyBullet's solver is a projected Gauss-Seidel too).
  PyBullet's erp acts on joint limits and motors; contacts keep theirs (the URDF's <contact> stiffness
  and damping, as the tutorials' <gazebo> kp and kd override ODE's erp for their surfaces).
- ode_config.sor_pgs_w, contact_surface_layer, contact_max_correcting_vel, max_contacts,
  sor_pgs_precon_iters > 0 and auto_disable_bodies true: PyBullet has no such setting; not honoured,
  said once in the log, and reported back by get_physics_properties as set.

A request is checked whole before anything changes: one bad number refuses all of it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

from .validation import MAX_GRAVITY, MAX_TIME_STEP, out_of_bounds
from .world import MIN_TIME_STEP, SolverSettings

MAX_SOLVER_ITERATIONS = 1000  # more would make one physics step take seconds


@dataclass(frozen=True)
class OdeConfig:
    """gazebo_msgs/ODEPhysics. The defaults describe this sim: PyBullet's solver settings, and Gazebo's
    defaults for the settings PyBullet does not have."""

    auto_disable_bodies: bool = False
    sor_pgs_precon_iters: int = 0
    sor_pgs_iters: int = SolverSettings.iterations
    sor_pgs_w: float = 1.0  # PyBullet's Gauss-Seidel does no over-relaxation
    sor_pgs_rms_error_tol: float = SolverSettings.residual_threshold
    contact_surface_layer: float = 0.001
    contact_max_correcting_vel: float = 100.0
    cfm: float = SolverSettings.cfm
    erp: float = SolverSettings.erp
    max_contacts: int = 20


@dataclass(frozen=True)
class PhysicsProperties:
    """What set_physics_properties asks for (and get_physics_properties reports)."""

    time_step: float
    max_update_rate: float
    gravity: tuple[float, float, float]
    ode: OdeConfig


_NOT_IN_PYBULLET = {
    "sor_pgs_w": "PyBullet's solver does no over-relaxation (w = 1)",
    "contact_surface_layer": "PyBullet has no contact surface layer setting",
    "contact_max_correcting_vel": "PyBullet has no contact correcting velocity setting",
    "max_contacts": "PyBullet keeps at most 4 contact points per pair",
    "sor_pgs_precon_iters": "PyBullet's solver has no preconditioning",
    "auto_disable_bodies": "the sim never puts bodies to sleep",
}


def check(request: PhysicsProperties) -> str:
    """Why the request must be refused ("" if it may be applied); the reason names the field and value."""
    if not (math.isfinite(request.time_step) and MIN_TIME_STEP <= request.time_step <= MAX_TIME_STEP):
        return (f"time_step must be a finite number of seconds from {MIN_TIME_STEP:g} to {MAX_TIME_STEP:g}, got "
                f"{request.time_step!r}")
    if not (math.isfinite(request.max_update_rate) and request.max_update_rate >= 0.0):
        return f"max_update_rate must be a finite number >= 0 (0: as fast as possible), got {request.max_update_rate!r}"
    gravity = out_of_bounds("gravity", request.gravity, MAX_GRAVITY, "m/s^2")
    if gravity:
        return gravity
    ode = request.ode
    if not 1 <= ode.sor_pgs_iters <= MAX_SOLVER_ITERATIONS:
        return f"ode_config.sor_pgs_iters must be between 1 and {MAX_SOLVER_ITERATIONS}, got {ode.sor_pgs_iters}"
    for name in ("sor_pgs_rms_error_tol", "cfm", "contact_surface_layer", "contact_max_correcting_vel"):
        value = getattr(ode, name)
        if not (math.isfinite(value) and value >= 0.0):
            return f"ode_config.{name} must be a finite number >= 0, got {value!r}"
    if not (math.isfinite(ode.erp) and 0.0 <= ode.erp <= 1.0):
        return f"ode_config.erp must be between 0 and 1, got {ode.erp!r}"
    if not (math.isfinite(ode.sor_pgs_w) and ode.sor_pgs_w > 0.0):
        return f"ode_config.sor_pgs_w must be a finite number > 0, got {ode.sor_pgs_w!r}"
    return ""


def solver_settings(ode: OdeConfig) -> SolverSettings:
    return SolverSettings(iterations=int(ode.sor_pgs_iters), residual_threshold=float(ode.sor_pgs_rms_error_tol),
                          erp=float(ode.erp), cfm=float(ode.cfm))


def not_honoured(ode: OdeConfig) -> dict[str, str]:
    """The ode_config fields whose value PyBullet cannot apply, each with the reason."""
    ours = OdeConfig()
    honoured = {"sor_pgs_iters", "sor_pgs_rms_error_tol", "erp", "cfm"}
    always = {"contact_surface_layer", "contact_max_correcting_vel", "max_contacts"}  # no PyBullet equivalent
    return {f.name: f"{f.name} {getattr(ode, f.name)}: {_NOT_IN_PYBULLET[f.name]}" for f in fields(OdeConfig)
            if f.name not in honoured and (f.name in always or getattr(ode, f.name) != getattr(ours, f.name))}


def real_time_factor(max_update_rate: float, time_step: float) -> float:
    """Sim seconds per wall second for Gazebo's real-time update rate (physics steps per wall second)."""
    return max_update_rate * time_step
