"""Robot configuration for the simulator: ros_control-style controllers and Gazebo-plugin-style sensors.

The sim node loads one YAML (config/<robot>_sim.yaml) into its private namespace; `parse_robot_config`
turns that dict into the dataclasses below and names the offending parameter on any mistake. Nothing
here is robot specific: robots differ only by URDF and this YAML.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

JOINT_STATE_CONTROLLER = "joint_state_controller/JointStateController"
VELOCITY_CONTROLLER = "effort_controllers/JointVelocityController"
POSITION_CONTROLLER = "effort_controllers/JointPositionController"
SENSOR_TYPES = ("p3d", "imu", "contact")


class ConfigError(ValueError):
    """A parameter of the simulator is missing, mistyped or out of range; the message names it."""


@dataclass(frozen=True)
class PidGains:
    p: float
    i: float = 0.0
    d: float = 0.0
    i_clamp: float = 0.0  # symmetric bound on the integral term's contribution; 0 = no integral


@dataclass(frozen=True)
class JointControllerConfig:
    """An effort PID controller on one joint, listening on <robot_namespace>/<name>/command."""

    name: str
    type: str
    joint: str
    pid: PidGains

    @property
    def is_position(self) -> bool:
        return self.type == POSITION_CONTROLLER


@dataclass(frozen=True)
class SensorConfig:
    """A sensor of type p3d (odometry), imu or contact, attached to `link`."""

    name: str
    type: str
    link: str
    topic: str
    frame_id: str
    update_rate: float
    gaussian_noise: float = 0.0


@dataclass(frozen=True)
class CameraConfig:
    """The rendering camera: it follows the robot's base link, looking at it (raised by `z_offset` m) from
    `distance` m; `yaw` in degrees about world z (0: from -y looking along +y, 90: from +x looking along
    -x), `pitch` in degrees (negative: from above)."""

    distance: float = 1.5
    yaw: float = 0.0
    pitch: float = -20.0
    z_offset: float = 0.0
    fov: float = 60.0  # vertical field of view, degrees


@dataclass(frozen=True)
class RobotConfig:
    robot_namespace: str
    spawn_xyz: tuple[float, ...]   # x, y, z
    spawn_rpy: tuple[float, ...]   # roll, pitch, yaw
    joint_state_rate: float
    controllers: tuple[JointControllerConfig, ...]
    sensors: tuple[SensorConfig, ...]
    joint_state_controller: str = "joint_state_controller"  # the name of the JointStateController
    camera: CameraConfig = CameraConfig()

    @property
    def joint_states_topic(self) -> str:
        return f"{self.robot_namespace}/joint_states"

    def command_topic(self, controller: JointControllerConfig) -> str:
        return f"{self.robot_namespace}/{controller.name}/command"


def _number(params: Mapping[str, Any], key: str, where: str, default: float | None = None,
            minimum: float | None = None, exclusive_minimum: bool = False) -> float:
    if key not in params:
        if default is None:
            raise ConfigError(f"missing parameter {where}/{key}")
        return float(default)
    value = params[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"parameter {where}/{key} must be a finite number, got {value!r}")
    if minimum is not None and (value < minimum or (exclusive_minimum and value == minimum)):
        relation = ">" if exclusive_minimum else ">="
        raise ConfigError(f"parameter {where}/{key} must be {relation} {minimum}, got {value!r}")
    return float(value)


def _text(params: Mapping[str, Any], key: str, where: str, default: str | None = None) -> str:
    value = params.get(key, default)
    if value is None:
        raise ConfigError(f"missing parameter {where}/{key}")
    if not isinstance(value, str) or not value:
        raise ConfigError(f"parameter {where}/{key} must be a non-empty string, got {value!r}")
    return value


def _mapping(params: Mapping[str, Any], key: str, where: str) -> dict[str, Any]:
    value = params.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"parameter {where}/{key} must be a dictionary, got {value!r}")
    return value


def parse_robot_config(params: Mapping[str, Any], where: str = "~") -> RobotConfig:
    """Build a RobotConfig from the sim node's private parameters (`where` prefixes error messages)."""
    namespace = _text(params, "robot_namespace", where)
    if not namespace.startswith("/"):
        raise ConfigError(f"parameter {where}/robot_namespace must be absolute (start with '/'), got {namespace!r}")
    namespace = namespace.rstrip("/")
    spawn = _mapping(params, "spawn", where)
    spawn_where = f"{where}/spawn"
    xyz = tuple(_number(spawn, k, spawn_where, 0.0) for k in ("x", "y", "z"))
    rpy = tuple(_number(spawn, k, spawn_where, 0.0) for k in ("roll", "pitch", "yaw"))

    controllers = []
    joint_state_rate = joint_state_controller = None
    for name, entry in sorted(_mapping(params, "controllers", where).items()):
        c_where = f"{where}/controllers/{name}"
        if not isinstance(entry, dict):
            raise ConfigError(f"parameter {c_where} must be a dictionary")
        ctype = _text(entry, "type", c_where)
        if ctype == JOINT_STATE_CONTROLLER:
            if joint_state_controller is not None:
                raise ConfigError(f"parameter {where}/controllers has two {JOINT_STATE_CONTROLLER}s: "
                                  f"{joint_state_controller} and {name}")
            joint_state_rate = _number(entry, "publish_rate", c_where, minimum=0.0, exclusive_minimum=True)
            joint_state_controller = name
            continue
        if ctype not in (VELOCITY_CONTROLLER, POSITION_CONTROLLER):
            raise ConfigError(f"parameter {c_where}/type: unsupported controller type {ctype!r} "
                              f"(supported: {JOINT_STATE_CONTROLLER}, {VELOCITY_CONTROLLER}, {POSITION_CONTROLLER})")
        pid = _mapping(entry, "pid", c_where)
        p_where = f"{c_where}/pid"
        gains = PidGains(p=_number(pid, "p", p_where), i=_number(pid, "i", p_where, 0.0),
                         d=_number(pid, "d", p_where, 0.0), i_clamp=_number(pid, "i_clamp", p_where, 0.0, minimum=0.0))
        joint = _text(entry, "joint", c_where)
        controllers.append(JointControllerConfig(name=name, type=ctype, joint=joint, pid=gains))
    if joint_state_rate is None or joint_state_controller is None:
        raise ConfigError(f"parameter {where}/controllers needs a {JOINT_STATE_CONTROLLER} with a publish_rate")

    sensors = []
    for name, entry in sorted(_mapping(params, "sensors", where).items()):
        s_where = f"{where}/sensors/{name}"
        if not isinstance(entry, dict):
            raise ConfigError(f"parameter {s_where} must be a dictionary")
        stype = _text(entry, "type", s_where)
        if stype not in SENSOR_TYPES:
            raise ConfigError(f"parameter {s_where}/type: unsupported sensor type {stype!r} "
                              f"(supported: {', '.join(SENSOR_TYPES)})")
        topic = _text(entry, "topic", s_where)
        if not topic.startswith("/"):
            raise ConfigError(f"parameter {s_where}/topic must be absolute (start with '/'), got {topic!r}")
        sensors.append(SensorConfig(
            name=name, type=stype, link=_text(entry, "link", s_where), topic=topic,
            frame_id=_text(entry, "frame_id", s_where),
            update_rate=_number(entry, "update_rate", s_where, minimum=0.0, exclusive_minimum=True),
            gaussian_noise=_number(entry, "gaussian_noise", s_where, 0.0, minimum=0.0)))
    camera = _mapping(params, "camera", where)
    c_where, default = f"{where}/camera", CameraConfig()
    known = [f.name for f in fields(CameraConfig)]
    unknown = sorted(set(camera) - set(known))
    if unknown:
        raise ConfigError(f"parameter {c_where} has unknown keys {unknown} (known: {', '.join(known)})")
    camera_config = CameraConfig(
        distance=_number(camera, "distance", c_where, default.distance, minimum=0.0, exclusive_minimum=True),
        yaw=_number(camera, "yaw", c_where, default.yaw), pitch=_number(camera, "pitch", c_where, default.pitch),
        z_offset=_number(camera, "z_offset", c_where, default.z_offset),
        fov=_number(camera, "fov", c_where, default.fov, minimum=0.0, exclusive_minimum=True))
    if camera_config.fov >= 180.0:
        raise ConfigError(f"parameter {c_where}/fov must be < 180 degrees, got {camera_config.fov!r}")
    return RobotConfig(robot_namespace=namespace, spawn_xyz=xyz, spawn_rpy=rpy, joint_state_rate=joint_state_rate,
                       controllers=tuple(controllers), sensors=tuple(sensors),
                       joint_state_controller=joint_state_controller, camera=camera_config)
