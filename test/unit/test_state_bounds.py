"""Absurd but finite state values (pybullet_sim.validation's bounds) and readings that are not finite numbers
(robot_rl.backends): what the sim refuses, naming the field and the bound, and what an env refuses to pass on."""
import copy
import math

import pybullet as p
import pytest
import yaml

from hopper_training.robot import MONOPED
from moving_cube_training.robot import MOVING_CUBE
from pybullet_sim import physics_properties
from pybullet_sim.config import parse_robot_config
from pybullet_sim.readings import FrameState, JointStateReading, OdometryReading
from pybullet_sim.transforms import normalized
from pybullet_sim.validation import (
    MAX_GRAVITY,
    MAX_POSITION,
    MAX_SPEED,
    MAX_TIME_STEP,
    ConfigError,
    frame_state_problem,
    param,
)
from pybullet_sim.world import DEFAULT_GRAVITY, World
from robot_rl import DirectBackend, Readings, SimStateError, non_finite_problem

REST = ((0.0, 0.0, 0.5), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3, (0.0,) * 3)


def state(position=REST[0], orientation=REST[1], linear=REST[2], angular=REST[3]) -> FrameState:
    return FrameState(position, orientation, linear, angular)


@pytest.mark.parametrize("wanted, expected", [
    (state(position=(1e30, 0.0, 0.5)),
     f"pose.position.x must be a finite number within +-{MAX_POSITION:g} m, got 1e+30"),
    (state(position=(0.0, 0.0, -1.1e6)), "pose.position.z must be a finite number within +-1e+06 m"),
    (state(linear=(0.0, 1e30, 0.0)), f"twist.linear.y must be a finite number within +-{MAX_SPEED:g} m/s, got 1e+30"),
    (state(angular=(0.0, 0.0, -1001.0)), "twist.angular.z must be a finite number within +-1000 rad/s, got -1001.0"),
    (state(orientation=(0.0, 0.0, 0.0, math.inf)), "pose.orientation must be finite numbers"),
    (state(position=(math.nan, 0.0, 0.0)), "pose.position.x must be a finite number"),
], ids=["far_position", "deep_position", "fast_linear", "fast_angular", "infinite_orientation", "nan_position"])
def test_a_state_beyond_the_bounds_names_the_field_and_the_bound(wanted, expected):
    assert frame_state_problem(*vars(wanted).values()).startswith(expected)


def test_a_state_at_the_bounds_and_any_finite_orientation_are_taken():
    at_bounds = state((MAX_POSITION, -MAX_POSITION, 0.0), (1e300, 1e-300, 0.0, 0.0), (MAX_SPEED,) * 3,
                      (-MAX_SPEED,) * 3)
    assert frame_state_problem(*vars(at_bounds).values()) == ""


@pytest.mark.parametrize("quaternion, expected", [
    ((1e200, 1e200, 0.0, 0.0), (math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0)),
    ((0.0, 0.0, 0.0, 1e300), (0.0, 0.0, 0.0, 1.0)),
    ((1e-13, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),  # nearly zero: no rotation, as Gazebo takes it
])
def test_a_huge_or_tiny_quaternion_normalises_to_a_unit_one(quaternion, expected):
    assert normalized(quaternion) == pytest.approx(expected)


@pytest.fixture
def cube(cube_urdf, cube_params):
    world = World(cube_urdf, parse_robot_config(copy.deepcopy(cube_params)))
    yield world
    world.close()


def test_the_world_refuses_a_far_position_and_changes_nothing(cube):
    before = cube.model_state()
    with pytest.raises(ValueError, match=r"pose.position.x must be a finite number within \+-1e\+06 m"):
        cube.set_model_state(state(position=(1e30, 0.0, 0.5)))
    assert cube.model_state() == before


def test_a_quaternion_of_1e200_leaves_the_world_finite(cube):
    """Its squares overflowed to inf, the normalised quaternion was all zeros, and PyBullet's state became NaN."""
    cube.set_model_state(state(orientation=(1e200, 1e200, 0.0, 0.0)))
    cube.step(10)
    assert all(math.isfinite(v) for v in (*cube.model_state().position, *cube.model_state().orientation))


@pytest.mark.parametrize("robot", [MOVING_CUBE, MONOPED], ids=["cube", "hopper"])
@pytest.mark.parametrize("time_step", [0.001, MAX_TIME_STEP])
def test_a_world_at_every_bound_at_once_stays_finite(robot, time_step):
    """Gravity, position, speeds at their bounds and commands of 1e300 on every controller, at the shortest usual
    and the longest time step: the bounds keep the physics finite (beyond them a quaternion of 1e200 did not)."""
    world = World(robot.urdf_path.read_text(), parse_robot_config(yaml.safe_load(robot.sim_config_path.read_text())),
                  time_step=time_step)
    try:
        world.set_gravity((MAX_GRAVITY, -MAX_GRAVITY, -MAX_GRAVITY))
        world.set_model_state(state((MAX_POSITION, MAX_POSITION, 0.5), (0.3, 0.1, 0.2, 0.9), (MAX_SPEED, -MAX_SPEED,
                                    MAX_SPEED), (MAX_SPEED, MAX_SPEED, -MAX_SPEED)))
        for controller in world.controller_names:
            world.set_command(controller, 1e300)
        world.step(200)
        model, joints = world.model_state(), world.read_joint_states()
        numbers = (*model.position, *model.orientation, *model.linear_velocity, *model.angular_velocity,
                   *joints.position, *joints.velocity, *joints.effort)
        assert all(math.isfinite(v) for v in numbers), (model, joints)
    finally:
        world.close()


def physics(time_step=0.001, gravity=DEFAULT_GRAVITY) -> physics_properties.PhysicsProperties:
    return physics_properties.PhysicsProperties(time_step, 1000.0, gravity, physics_properties.OdeConfig())


@pytest.mark.parametrize("request_, expected", [
    (physics(gravity=(0.0, 0.0, -1e30)),
     f"gravity.z must be a finite number within +-{MAX_GRAVITY:g} m/s^2, got -1e+30"),
    (physics(time_step=1e30),
     f"time_step must be a finite number of seconds from 1e-06 to {MAX_TIME_STEP:g}, got 1e+30"),
    (physics(time_step=2.0), "time_step must be a finite number of seconds from 1e-06 to 1, got 2.0"),
], ids=["gravity", "huge_time_step", "time_step_above_the_bound"])
def test_physics_beyond_the_bounds_is_refused_naming_the_field_and_the_bound(request_, expected):
    assert physics_properties.check(request_) == expected


def test_physics_at_the_bounds_is_taken():
    assert physics_properties.check(physics(time_step=MAX_TIME_STEP, gravity=(MAX_GRAVITY, -MAX_GRAVITY, 0.0))) == ""


def test_a_param_above_its_maximum_names_it_and_the_maximum():
    with pytest.raises(ConfigError, match=r"parameter ~time_step must be <= 1, got 1e\+30"):
        param({"time_step": 1e30}, "time_step", float, "~", 0.001, minimum=1e-6, maximum=MAX_TIME_STEP)
    assert param({"time_step": 1.0}, "time_step", float, "~", maximum=MAX_TIME_STEP) == 1.0


# -- readings that are not finite -----------------------------------------------------------------
def readings(x: float) -> Readings:
    joints = JointStateReading(1.5, ("wheel",), (0.0,), (0.0,), (0.0,))
    odom = OdometryReading(1.5, "world", "cube_body", (x, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3, (0.0,) * 3)
    return Readings(joints, {"odom": odom})


def test_a_non_finite_reading_is_named():
    problem = non_finite_problem(readings(math.nan))
    assert problem.startswith("the sim's state is no longer finite at sim time 1.500000 s: odom.position[0] = nan;")
    assert "restart the sim" in problem
    assert non_finite_problem(readings(1e300)) == ""


def test_the_direct_backend_refuses_to_pass_on_a_state_that_blew_up():
    backend = DirectBackend(MOVING_CUBE.urdf_path, MOVING_CUBE.sim_config_path)
    try:
        world = backend.world
        p.resetBaseVelocity(world._body, (math.nan, 0.0, 0.0), (0.0, 0.0, 0.0), physicsClientId=world._cid)
        with pytest.raises(SimStateError, match=r"the sim's state is no longer finite at sim time 0.010000 s: \w+"):
            backend.step(10)
    finally:
        backend.close()



def test_the_ros_backend_refuses_an_answer_with_a_non_finite_number():
    """The lockstep answer's numbers (pybullet_sim/PackedReadings) are summed once per step; a NaN among them is
    named. No sim is needed: the answer is made here as the sim node packs it."""
    from pybullet_sim.msg import PackedReadings
    from pybullet_sim.ros.client import SimConnectionError
    from pybullet_sim.sensors import pack_readings
    from robot_rl import RosBackend

    backend = RosBackend.__new__(RosBackend)  # the answer's reader alone, without the connection
    backend._sensor_names, backend._sensor_types = ["odom"], ["p3d"]
    for x, finite in ((1e300, True), (math.inf, False), (math.nan, False)):
        values, names = pack_readings(readings(x).joints, [readings(x).odometry("odom")])
        answer = PackedReadings(values=values, names=names)
        if finite:
            assert backend._readings(answer).odometry("odom").position[0] == x
        else:
            with pytest.raises(SimConnectionError, match=rf"at sim time 1.500000 s: odom.position\[0\] = {x!r};"):
                backend._readings(answer)
