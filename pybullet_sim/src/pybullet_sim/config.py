"""Robot configuration for the simulator: ros_control-style controllers and Gazebo-plugin-style sensors.

The sim node loads one YAML (config/<robot>_sim.yaml) into its private namespace; `parse_robot_config`
turns that dict into the dataclasses below and names the offending parameter on any mistake. Nothing
here is robot specific: robots differ only by URDF and this YAML.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
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
    MAX_SCENE_SIZE,
    MAX_SPAWN_ANGLE,
    param,
)

__all__ = ["CameraConfig", "PolesConfig", "RobotConfig", "parse_camera", "parse_robot_config"]

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


CAMERA_FOLLOWS = ("base", "horizontal", "fixed")


@dataclass(frozen=True)
class PolesConfig:
    """Height poles in the rendered scene (no physics): at each x of `xs`, at `y`, a pole `height` m tall in
    bands of `band` m, alternately dark and light, so that a frame shows heights."""

    xs: tuple[float, ...] = ()
    y: float = 0.0
    height: float = 1.0
    band: float = 0.1


@dataclass(frozen=True)
class CameraConfig:
    """The rendering camera and what the rendered scene shows beside the robot.

    The camera looks from `distance` m at an aim point; `yaw` in degrees about world z (0: from -y looking along
    +y, 90: from +x looking along -x), `pitch` in degrees (negative: from above). `follow` says where the aim is:
    "base": at the robot's base, raised by `z_offset` m (it moves with every hop); "horizontal": above the base's
    x, y at the fixed height `target_height` (the ground stays still in the picture, a hop is seen as one);
    "fixed": at the spawn's x, y and `target_height`. `shadows` casts them from a light in `light_direction`
    (towards the light); `contact_color` (RGBA, empty: none) colours each contact sensor's link while it
    touches something; `ground_marks` draws a dark disc on the ground straight under each contact sensor's link
    (a shadow from right above), so that a frame shows the gap under a foot in the air; `poles` puts height
    poles in the scene."""

    distance: float = 1.5
    yaw: float = 0.0
    pitch: float = -20.0
    z_offset: float = 0.0
    fov: float = 60.0  # vertical field of view, degrees
    follow: str = "base"  # one of CAMERA_FOLLOWS
    target_height: float = 0.5  # m above the ground: the aim's height unless follow is "base"
    shadows: bool = False
    light_direction: tuple[float, ...] = (0.0, -0.4, 1.0)
    contact_color: tuple[float, ...] = ()
    ground_marks: bool = False
    poles: PolesConfig = PolesConfig()


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
    camera_config = parse_camera(param(params, "camera", dict, top, {}), f"{where}/camera")
    base_constraint = param(params, "base_constraint", str, top, "none", choices=BASE_CONSTRAINTS)
    return RobotConfig(robot_namespace=namespace, spawn_xyz=xyz, spawn_rpy=rpy, joint_state_rate=joint_state_rate,
                       controllers=tuple(controllers), sensors=tuple(sensors),
                       joint_state_controller=joint_state_controller, camera=camera_config,
                       base_constraint=base_constraint)


def _floats(value: Any, name: str, count: int | None = None, bound: float = MAX_POSITION) -> tuple[float, ...]:
    """A list of finite numbers within +-bound (`count` of them when given), or a ConfigError naming it."""
    if (not isinstance(value, (list, tuple)) or (count is not None and len(value) != count)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and abs(v) <= bound
                       for v in value)):
        size = f"{count} " if count is not None else ""
        raise ConfigError(f"parameter {name} must be a list of {size}finite numbers within +-{bound:g}, got {value!r}")
    return tuple(float(v) for v in value)


def _known_keys(section: Mapping[str, Any], known: Sequence[str], where: str) -> None:
    unknown = sorted(set(section) - set(known))
    if unknown:
        raise ConfigError(f"parameter {where} has unknown keys {unknown} (known: {', '.join(known)})")


def parse_camera(camera: Mapping[str, Any], where: str) -> CameraConfig:
    """The `camera:` section of a robot's sim config (`where` names it in errors)."""
    default, prefix = CameraConfig(), where + "/"
    _known_keys(camera, [f.name for f in fields(CameraConfig)], where)
    poles = param(camera, "poles", dict, prefix, {})
    _known_keys(poles, [f.name for f in fields(PolesConfig)], prefix + "poles")
    p_prefix, no_poles = prefix + "poles/", PolesConfig()
    poles_config = PolesConfig(
        xs=_floats(poles.get("xs", []), p_prefix + "xs"),
        y=param(poles, "y", float, p_prefix, no_poles.y, minimum=-MAX_POSITION, maximum=MAX_POSITION),
        height=param(poles, "height", float, p_prefix, no_poles.height, minimum=0.0, exclusive_minimum=True,
                     maximum=MAX_SCENE_SIZE),
        band=param(poles, "band", float, p_prefix, no_poles.band, minimum=0.01, maximum=MAX_SCENE_SIZE))
    contact_color = _floats(camera.get("contact_color", []), prefix + "contact_color", bound=1.0)
    if contact_color and (len(contact_color) != 4 or min(contact_color) < 0.0):
        raise ConfigError(f"parameter {prefix}contact_color must be [] or RGBA, four numbers from 0 to 1, got "
                          f"{camera['contact_color']!r}")
    light = _floats(camera.get("light_direction", list(default.light_direction)), prefix + "light_direction", 3)
    if not any(light):
        raise ConfigError(f"parameter {prefix}light_direction must not be all zeros")
    config = CameraConfig(
        distance=param(camera, "distance", float, prefix, default.distance, minimum=0.0,
                       exclusive_minimum=True, maximum=MAX_POSITION),
        yaw=param(camera, "yaw", float, prefix, default.yaw, minimum=-MAX_CAMERA_ANGLE, maximum=MAX_CAMERA_ANGLE),
        pitch=param(camera, "pitch", float, prefix, default.pitch, minimum=-MAX_CAMERA_ANGLE, maximum=MAX_CAMERA_ANGLE),
        z_offset=param(camera, "z_offset", float, prefix, default.z_offset, minimum=-MAX_POSITION,
                       maximum=MAX_POSITION),
        fov=param(camera, "fov", float, prefix, default.fov, minimum=0.0, exclusive_minimum=True),
        follow=param(camera, "follow", str, prefix, default.follow, choices=CAMERA_FOLLOWS),
        target_height=param(camera, "target_height", float, prefix, default.target_height, minimum=-MAX_POSITION,
                            maximum=MAX_POSITION),
        shadows=param(camera, "shadows", bool, prefix, default.shadows), light_direction=light,
        contact_color=contact_color, ground_marks=param(camera, "ground_marks", bool, prefix, default.ground_marks),
        poles=poles_config)
    if config.fov >= 180.0:
        raise ConfigError(f"parameter {prefix}fov must be < 180 degrees, got {config.fov!r}")
    return config
