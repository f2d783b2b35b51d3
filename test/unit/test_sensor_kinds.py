"""The registry of sensor kinds (pybullet_sim.sensors) and the joint limits read from the URDF (pybullet_sim.urdf).

Every kind is complete: the World reads it as its reading type, its message converts both ways,
pybullet_sim/Readings has its field, and the sim config accepts exactly the registered kinds."""
import math

import pybullet as p
import pytest
import rospy
import yaml

from hopper_training.robot import JOINTS, MONOPED
from moving_cube_training.robot import MOVING_CUBE
from pybullet_sim.config import parse_robot_config
from pybullet_sim.errors import ConfigError
from pybullet_sim.msg import Readings
from pybullet_sim.ros.messages import SENSOR_MESSAGES
from pybullet_sim.sensors import SENSOR_KINDS
from pybullet_sim.urdf import parse_urdf_joints
from pybullet_sim.world import World

ROBOTS = {"cube": MOVING_CUBE, "hopper": MONOPED}


@pytest.fixture(scope="module")
def worlds():
    """Each robot's World after a few steps (the hopper's foot on the ground), with its sensors' readings."""
    made = {}
    for name, robot in ROBOTS.items():
        config = parse_robot_config(yaml.safe_load(robot.sim_config_path.read_text()))
        world = World(robot.urdf_path.read_text(), config)
        world.step(300)
        made[name] = world
    yield made
    for world in made.values():
        world.close()


def test_the_yaml_types_are_the_gazebo_plugins():
    assert list(SENSOR_KINDS) == ["p3d", "imu", "contact"]


def test_both_robots_use_every_kind_between_them(worlds):
    assert {sensor.type for world in worlds.values() for sensor in world.config.sensors} == set(SENSOR_KINDS)


@pytest.mark.parametrize("robot", ROBOTS)
def test_the_world_reads_each_sensor_as_its_kinds_reading(worlds, robot):
    world = worlds[robot]
    for sensor in world.config.sensors:
        assert isinstance(world.read_sensor(sensor), SENSOR_KINDS[sensor.type].reading)


@pytest.mark.parametrize("robot", ROBOTS)
def test_each_reading_goes_to_its_message_and_back(worlds, robot):
    world = worlds[robot]
    stamp = rospy.Time(0, world.time_ns)
    for sensor in world.config.sensors:
        side = SENSOR_MESSAGES[sensor.type]
        reading = world.read_sensor(sensor)
        message = side.to_message(reading, stamp)
        assert isinstance(message, side.type)
        assert side.to_reading(message) == reading


def test_readings_has_a_field_of_each_kinds_message():
    fields = dict(zip(Readings.__slots__, Readings._slot_types))
    for kind in SENSOR_KINDS.values():
        assert fields[kind.readings_field] == f"{SENSOR_MESSAGES[kind.name].type._type}[]"


def test_every_kind_has_its_message_side():
    assert list(SENSOR_MESSAGES) == list(SENSOR_KINDS)


def test_the_sim_config_takes_exactly_the_registered_kinds(cube_params):
    (sensor,) = cube_params["sensors"].values()
    for kind in SENSOR_KINDS:
        sensor["type"] = kind
        assert parse_robot_config(cube_params).sensors[0].type == kind
    sensor["type"] = "sonar"
    with pytest.raises(ConfigError, match="unsupported sensor type 'sonar' \\(supported: p3d, imu, contact\\)"):
        parse_robot_config(cube_params)


# -- joint limits from the URDF -------------------------------------------------------------------
def test_the_monopeds_joint_limits():
    assert MONOPED.joint_limits(JOINTS) == ((-1.6, 1.6), (-1.6, 1.6), (-1.6, 0.0))


def test_the_cubes_wheel_speed_limit():
    assert MOVING_CUBE.joints()["inertia_wheel_roll_joint"].velocity == 1000.0


@pytest.mark.parametrize("robot", ROBOTS)
def test_the_urdf_limits_are_those_pybullet_loads(worlds, robot):
    """What task envs read from the URDF is what the sim clamps commands to."""
    world, joints = worlds[robot], ROBOTS[robot].joints()
    body, cid = world._body, world._cid
    for index in range(p.getNumJoints(body, physicsClientId=cid)):
        info = p.getJointInfo(body, index, physicsClientId=cid)
        joint = joints[info[1].decode()]
        if joint.type in ("revolute", "continuous", "prismatic"):
            assert (joint.effort, joint.velocity) == (info[10], info[11])
        if joint.type in ("revolute", "prismatic"):
            assert (joint.lower, joint.upper) == (info[8], info[9])


def test_limits_absent_or_not_numbers():
    urdf = ('<robot name="r"><link name="a"/><joint name="free" type="continuous"/>'
            '<joint name="odd" type="revolute"><limit lower="x" upper="1"/></joint></robot>')
    name, joints = parse_urdf_joints(urdf, "test")
    assert name == "r"
    assert (joints["free"].lower, joints["free"].upper, joints["free"].velocity) == (0.0, 0.0, 0.0)
    assert math.isnan(joints["odd"].lower) and joints["odd"].upper == 1.0
