"""Unit tests for pybullet_sim.config.parse_robot_config (no ROS, no physics)."""
import math

import pytest

from pybullet_sim.config import JOINT_STATE_CONTROLLER, VELOCITY_CONTROLLER, parse_robot_config
from pybullet_sim.errors import ConfigError

WHEEL = "inertia_wheel_roll_joint_velocity_controller"
P3D = "p3d_base_controller"


def config_error(params):
    """Parse `params`, expect a ConfigError, return its message."""
    with pytest.raises(ConfigError) as info:
        parse_robot_config(params)
    return str(info.value)


def test_cube_yaml_topics_rates_and_noise(cube_params):
    """The cube YAML yields the tutorial's topics, rates, gains and noise."""
    config = parse_robot_config(cube_params)
    assert config.robot_namespace == "/moving_cube"
    assert config.joint_states_topic == "/moving_cube/joint_states"
    assert config.joint_state_rate == 30.0
    assert config.spawn_xyz == (0.0, 0.0, 0.11)
    assert config.spawn_rpy == (0.0, 0.0, 0.0)

    (controller,) = config.controllers  # the joint_state_controller is not a joint controller
    assert controller.name == WHEEL
    assert controller.type == VELOCITY_CONTROLLER
    assert not controller.is_position
    assert controller.joint == "inertia_wheel_roll_joint"
    assert (controller.pid.p, controller.pid.i, controller.pid.d) == (1.0, 0.0, 0.0)
    assert config.command_topic(controller) == f"/moving_cube/{WHEEL}/command"

    (sensor,) = config.sensors
    assert (sensor.name, sensor.type, sensor.link) == (P3D, "p3d", "cube_body")
    assert sensor.topic == "/moving_cube/odom"
    assert sensor.frame_id == "world"
    assert sensor.update_rate == 50.0
    assert sensor.gaussian_noise == 0.01


def test_trailing_slash_of_namespace_is_dropped(cube_params):
    """'/moving_cube/' gives the same topics as '/moving_cube' (no '//')."""
    cube_params["robot_namespace"] = "/moving_cube/"
    assert parse_robot_config(cube_params).joint_states_topic == "/moving_cube/joint_states"


def test_missing_robot_namespace(cube_params):
    del cube_params["robot_namespace"]
    assert "~/robot_namespace" in config_error(cube_params)


def test_relative_robot_namespace(cube_params):
    cube_params["robot_namespace"] = "moving_cube"
    message = config_error(cube_params)
    assert "~/robot_namespace" in message
    assert "absolute" in message


def test_unknown_controller_type(cube_params):
    cube_params["controllers"][WHEEL]["type"] = "effort_controllers/JointTrajectoryController"
    message = config_error(cube_params)
    assert f"~/controllers/{WHEEL}/type" in message
    assert "effort_controllers/JointTrajectoryController" in message


def test_missing_pid_p(cube_params):
    del cube_params["controllers"][WHEEL]["pid"]["p"]
    assert f"~/controllers/{WHEEL}/pid/p" in config_error(cube_params)


@pytest.mark.parametrize("value", ["high", None, True, float("nan"), float("inf")])
def test_non_number_pid_p(cube_params, value):
    """A string, null, bool or non-finite value where a number is expected is rejected by path."""
    cube_params["controllers"][WHEEL]["pid"]["p"] = value
    message = config_error(cube_params)
    assert f"~/controllers/{WHEEL}/pid/p" in message
    assert "number" in message


@pytest.mark.parametrize("value", [-50, 0])
def test_non_positive_sensor_update_rate(cube_params, value):
    cube_params["sensors"][P3D]["update_rate"] = value
    assert f"~/sensors/{P3D}/update_rate" in config_error(cube_params)


def test_negative_joint_state_publish_rate(cube_params):
    cube_params["controllers"]["joint_state_controller"]["publish_rate"] = -30
    assert "~/controllers/joint_state_controller/publish_rate" in config_error(cube_params)


def test_negative_gaussian_noise(cube_params):
    cube_params["sensors"][P3D]["gaussian_noise"] = -0.01
    assert f"~/sensors/{P3D}/gaussian_noise" in config_error(cube_params)


def test_sensor_with_relative_topic(cube_params):
    cube_params["sensors"][P3D]["topic"] = "moving_cube/odom"
    message = config_error(cube_params)
    assert f"~/sensors/{P3D}/topic" in message
    assert "absolute" in message


def test_no_joint_state_controller(cube_params):
    del cube_params["controllers"]["joint_state_controller"]
    message = config_error(cube_params)
    assert "~/controllers" in message
    assert JOINT_STATE_CONTROLLER in message


def test_where_prefixes_the_parameter_path(cube_params):
    """The `where` argument replaces '~' in error messages."""
    del cube_params["robot_namespace"]
    with pytest.raises(ConfigError, match="/pybullet_sim/robot_namespace"):
        parse_robot_config(cube_params, where="/pybullet_sim")


@pytest.mark.parametrize("section, key, value, expected", [
    ("spawn", "z", 1e30, "parameter ~/spawn/z must be <= 1e+06, got 1e+30"),
    ("spawn", "x", -2e6, "parameter ~/spawn/x must be >= -1e+06, got -2000000.0"),
    ("spawn", "yaw", 90.0, "parameter ~/spawn/yaw must be <= 6.28319, got 90.0"),
    ("spawn", "roll", -7.0, "parameter ~/spawn/roll must be >= -6.28319, got -7.0"),
    ("pid", "p", 1e9, f"parameter ~/controllers/{WHEEL}/pid/p must be <= 1e+06, got 1000000000.0"),
    ("pid", "i", 2e6, f"parameter ~/controllers/{WHEEL}/pid/i must be <= 1e+06, got 2000000.0"),
    ("pid", "d", -1e30, f"parameter ~/controllers/{WHEEL}/pid/d must be >= -1e+06, got -1e+30"),
    ("pid", "i_clamp", 1e7, f"parameter ~/controllers/{WHEEL}/pid/i_clamp must be <= 1e+06, got 10000000.0"),
    ("noise", "gaussian_noise", 5.0, f"parameter ~/sensors/{P3D}/gaussian_noise must be <= 1, got 5.0"),
    ("noise", "update_rate", 1e9, f"parameter ~/sensors/{P3D}/update_rate must be <= 1e+06, got 1000000000.0"),
    ("joint_states", "publish_rate", 2e6,
     "parameter ~/controllers/joint_state_controller/publish_rate must be <= 1e+06, got 2000000.0"),
    ("camera", "yaw", 1e4, "parameter ~/camera/yaw must be <= 360, got 10000.0"),
    ("camera", "pitch", -400.0, "parameter ~/camera/pitch must be >= -360, got -400.0"),
    ("camera", "distance", 1e30, "parameter ~/camera/distance must be <= 1e+06, got 1e+30"),
    ("camera", "z_offset", -1e7, "parameter ~/camera/z_offset must be >= -1e+06, got -10000000.0"),
])
def test_absurd_spawn_pose_gains_and_noise_are_refused_naming_the_bound(cube_params, section, key, value, expected):
    where = {"spawn": cube_params["spawn"], "pid": cube_params["controllers"][WHEEL]["pid"],
             "noise": cube_params["sensors"][P3D], "joint_states": cube_params["controllers"]["joint_state_controller"],
             "camera": cube_params.setdefault("camera", {})}[section]
    where[key] = value
    assert config_error(cube_params) == expected


def test_values_at_the_bounds_are_taken(cube_params):
    cube_params["spawn"].update(x=1e6, y=-1e6, yaw=2 * math.pi, roll=-2 * math.pi)
    cube_params["controllers"][WHEEL]["pid"].update(p=1e6, i=-1e6, d=1e6)
    cube_params["sensors"][P3D].update(gaussian_noise=1.0, update_rate=1e6)
    cube_params["controllers"][WHEEL]["pid"]["i_clamp"] = 1e6
    cube_params["camera"] = {"yaw": -360.0, "pitch": 360.0, "distance": 1e6, "z_offset": -1e6}
    config = parse_robot_config(cube_params)
    assert config.camera.yaw == -360.0 and config.camera.distance == 1e6 and config.sensors[0].update_rate == 1e6
    assert config.spawn_xyz[:2] == (1e6, -1e6) and config.spawn_rpy[::2] == (-2 * math.pi, 2 * math.pi)
    assert (config.controllers[0].pid.p, config.controllers[0].pid.i) == (1e6, -1e6)
    assert config.sensors[0].gaussian_noise == 1.0
