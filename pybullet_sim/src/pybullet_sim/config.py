"""Robot configuration for the simulator: ros_control-style controllers and Gazebo-plugin-style sensors.

The sim node loads one YAML (config/<robot>_sim.yaml) into its private namespace; `parse_robot_config`
turns that dict into the dataclasses below and names the offending parameter on any mistake. Nothing
here is robot specific: robots differ only by URDF and this YAML.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from .errors import ConfigError
from .sensors import SENSOR_KINDS
from .validation import (
    MAX_CAMERA_ANGLE,
    MAX_GAIN,
    MAX_NOISE,
    MAX_POSITION,
    MAX_RATE,
    MAX_SPAWN_ANGLE,
    param,
)

__all__ = ["RobotConfig", "parse_robot_config"]

JOINT_STATE_CONTROLLER = "joint_state_controller/JointStateController"
VELOCITY_CONTROLLER = "effort_controllers/JointVelocityController"
POSITION_CONTROLLER = "effort_controllers/JointPositionController"
BASE_CONSTRAINTS = ("none", "vertical")  # vertical: the base slides along world z only, kept at its spawn x, y and
                                         # orientation (a prismatic constraint to the world; hopping's first stage)


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
    base_constraint: str = "none"  # one of BASE_CONSTRAINTS

    @property
    def joint_states_topic(self) -> str:
        return f"{self.robot_namespace}/joint_states"

    def command_topic(self, controller: JointControllerConfig) -> str:
        return f"{self.robot_namespace}/{controller.name}/command"


def parse_robot_config(params: Mapping[str, Any], where: str = "~") -> RobotConfig:
    """Build a RobotConfig from the sim node's private parameters (`where` prefixes error messages)."""
    top = f"{where}/"
    namespace = param(params, "robot_namespace", str, top)
    if not namespace.startswith("/"):
        raise ConfigError(f"parameter {where}/robot_namespace must be absolute (start with '/'), got {namespace!r}")
    namespace = namespace.rstrip("/")
    spawn = param(params, "spawn", dict, top, {})
    spawn_where = f"{where}/spawn/"
    xyz = tuple(param(spawn, k, float, spawn_where, 0.0, minimum=-MAX_POSITION, maximum=MAX_POSITION)
                for k in ("x", "y", "z"))
    rpy = tuple(param(spawn, k, float, spawn_where, 0.0, minimum=-MAX_SPAWN_ANGLE, maximum=MAX_SPAWN_ANGLE)
                for k in ("roll", "pitch", "yaw"))

    controllers = []
    joint_state_rate = joint_state_controller = None
    for name, entry in sorted(param(params, "controllers", dict, top, {}).items()):
        c_where = f"{where}/controllers/{name}"
        if not isinstance(entry, dict):
            raise ConfigError(f"parameter {c_where} must be a dictionary")
        ctype = param(entry, "type", str, c_where + "/")
        if ctype == JOINT_STATE_CONTROLLER:
            if joint_state_controller is not None:
                raise ConfigError(f"parameter {where}/controllers has two {JOINT_STATE_CONTROLLER}s: "
                                  f"{joint_state_controller} and {name}")
            joint_state_rate = param(entry, "publish_rate", float, c_where + "/", minimum=0.0,
                                     exclusive_minimum=True, maximum=MAX_RATE)
            joint_state_controller = name
            continue
        if ctype not in (VELOCITY_CONTROLLER, POSITION_CONTROLLER):
            raise ConfigError(f"parameter {c_where}/type: unsupported controller type {ctype!r} "
                              f"(supported: {JOINT_STATE_CONTROLLER}, {VELOCITY_CONTROLLER}, {POSITION_CONTROLLER})")
        pid = param(entry, "pid", dict, c_where + "/", {})
        p_where = f"{c_where}/pid/"
        gains = PidGains(p=param(pid, "p", float, p_where, minimum=-MAX_GAIN, maximum=MAX_GAIN),
                         i=param(pid, "i", float, p_where, 0.0, minimum=-MAX_GAIN, maximum=MAX_GAIN),
                         d=param(pid, "d", float, p_where, 0.0, minimum=-MAX_GAIN, maximum=MAX_GAIN),
                         i_clamp=param(pid, "i_clamp", float, p_where, 0.0, minimum=0.0, maximum=MAX_GAIN))
        joint = param(entry, "joint", str, c_where + "/")
        controllers.append(JointControllerConfig(name=name, type=ctype, joint=joint, pid=gains))
    if joint_state_rate is None or joint_state_controller is None:
        raise ConfigError(f"parameter {where}/controllers needs a {JOINT_STATE_CONTROLLER} with a publish_rate")

    sensors = []
    for name, entry in sorted(param(params, "sensors", dict, top, {}).items()):
        s_where = f"{where}/sensors/{name}"
        if not isinstance(entry, dict):
            raise ConfigError(f"parameter {s_where} must be a dictionary")
        stype = param(entry, "type", str, s_where + "/")
        if stype not in SENSOR_KINDS:
            raise ConfigError(f"parameter {s_where}/type: unsupported sensor type {stype!r} "
                              f"(supported: {', '.join(SENSOR_KINDS)})")
        topic = param(entry, "topic", str, s_where + "/")
        if not topic.startswith("/"):
            raise ConfigError(f"parameter {s_where}/topic must be absolute (start with '/'), got {topic!r}")
        sensors.append(SensorConfig(
            name=name, type=stype, link=param(entry, "link", str, s_where + "/"), topic=topic,
            frame_id=param(entry, "frame_id", str, s_where + "/"),
            update_rate=param(entry, "update_rate", float, s_where + "/", minimum=0.0, exclusive_minimum=True,
                              maximum=MAX_RATE),
            gaussian_noise=param(entry, "gaussian_noise", float, s_where + "/", 0.0, minimum=0.0, maximum=MAX_NOISE)))
    camera = param(params, "camera", dict, top, {})
    c_where, default = f"{where}/camera", CameraConfig()
    known = [f.name for f in fields(CameraConfig)]
    unknown = sorted(set(camera) - set(known))
    if unknown:
        raise ConfigError(f"parameter {c_where} has unknown keys {unknown} (known: {', '.join(known)})")
    camera_config = CameraConfig(
        distance=param(camera, "distance", float, c_where + "/", default.distance, minimum=0.0,
                       exclusive_minimum=True, maximum=MAX_POSITION),
        yaw=param(camera, "yaw", float, c_where + "/", default.yaw, minimum=-MAX_CAMERA_ANGLE,
                  maximum=MAX_CAMERA_ANGLE),
        pitch=param(camera, "pitch", float, c_where + "/", default.pitch, minimum=-MAX_CAMERA_ANGLE,
                    maximum=MAX_CAMERA_ANGLE),
        z_offset=param(camera, "z_offset", float, c_where + "/", default.z_offset, minimum=-MAX_POSITION,
                       maximum=MAX_POSITION),
        fov=param(camera, "fov", float, c_where + "/", default.fov, minimum=0.0, exclusive_minimum=True))
    if camera_config.fov >= 180.0:
        raise ConfigError(f"parameter {c_where}/fov must be < 180 degrees, got {camera_config.fov!r}")
    base_constraint = param(params, "base_constraint", str, top, "none", choices=BASE_CONSTRAINTS)
    return RobotConfig(robot_namespace=namespace, spawn_xyz=xyz, spawn_rpy=rpy, joint_state_rate=joint_state_rate,
                       controllers=tuple(controllers), sensors=tuple(sensors),
                       joint_state_controller=joint_state_controller, camera=camera_config,
                       base_constraint=base_constraint)
