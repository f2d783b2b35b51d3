"""Unit tests for pybullet_sim.world.World on the moving cube, and for replayed starts also on the monoped
(PyBullet DIRECT, no ROS)."""
import copy
import inspect
import math

import pybullet as p
import pytest
import yaml

from pybullet_sim.config import parse_robot_config
from pybullet_sim.errors import ConfigError, UrdfError
from pybullet_sim.readings import OdometryReading
from pybullet_sim.world import World

WHEEL = "inertia_wheel_roll_joint_velocity_controller"
P3D = "p3d_base_controller"
TIME_STEP = 0.001
EFFORT_LIMIT = 200.0  # <limit effort="200"> of inertia_wheel_roll_joint
SPAWN = (0.0, 0.0, 0.11)
SOURCE = "parameter /robot_description"


@pytest.fixture
def make_world(cube_params, cube_urdf):
    """Factory for cube Worlds (optionally with another p3d noise or seed); closes them all afterwards."""
    worlds = []

    def make(noise=None, seed=0):
        params = copy.deepcopy(cube_params)
        if noise is not None:
            params["sensors"][P3D]["gaussian_noise"] = noise
        world = World(cube_urdf, parse_robot_config(params), time_step=TIME_STEP, seed=seed)
        worlds.append(world)
        return world

    yield make
    for world in worlds:
        world.close()


@pytest.fixture
def world(make_world):
    """The cube as configured (p3d noise 0.01)."""
    return make_world()


@pytest.fixture
def quiet_world(make_world):
    """The cube with a noise-free p3d sensor."""
    return make_world(noise=0.0)


def p3d(world):
    (sensor,) = world.config.sensors
    return sensor


def roll(world):
    return p.getEulerFromQuaternion(world.link_pose("cube_body")[1])[0]


def all_finite(values):
    return all(math.isfinite(v) for v in values)


# -- 1. velocity controller -----------------------------------------------------------------------
def test_wheel_reaches_commanded_speed(world):
    """50 rad/s is reached within 0.3 s; the effort column is the clamped P effort of each step."""
    assert world.joint_names == ("inertia_wheel_roll_joint",)
    assert world.read_joint_states().effort == (0.0,)
    assert world.set_command(WHEEL, 50.0) is True
    for _ in range(300):
        velocity_before = world.read_joint_states().velocity[0]
        world.step()
        effort = world.read_joint_states().effort[0]
        expected = max(-EFFORT_LIMIT, min(EFFORT_LIMIT, 1.0 * (50.0 - velocity_before)))  # pid p = 1
        assert effort == pytest.approx(expected, abs=1e-9)
        assert abs(effort) <= EFFORT_LIMIT
    state = world.read_joint_states()
    assert state.velocity[0] == pytest.approx(50.0, abs=1.0)
    assert state.stamp == pytest.approx(0.3)


def test_first_step_effort_is_non_zero_and_clamped(world):
    """Accelerating from rest: effort p * error (50) below the limit, exactly the limit above it."""
    world.set_command(WHEEL, 50.0)
    world.step()
    assert world.read_joint_states().effort == (50.0,)
    world.set_command(WHEEL, 1000.0)
    world.step()
    assert world.read_joint_states().effort == (EFFORT_LIMIT,)
    world.set_command(WHEEL, -1000.0)
    world.step()
    assert world.read_joint_states().effort == (-EFFORT_LIMIT,)


# -- 2. the reaction wheel rolls the cube ---------------------------------------------------------
def test_braking_spinning_wheel_rolls_cube_along_y(world):
    """Spinning up and then braking the wheel rolls the cube about x, in opposite senses, moving it along y."""
    world.set_command(WHEEL, 0.0)
    world.step(300)  # settle on the ground
    roll_rest, (x_rest, y_rest, _) = roll(world), world.link_pose("cube_body")[0]

    world.set_command(WHEEL, 100.0)
    world.step(700)
    assert world.read_joint_states().velocity[0] == pytest.approx(100.0, abs=1.0)
    roll_spun, (x_spun, y_spun, _) = roll(world), world.link_pose("cube_body")[0]

    world.set_command(WHEEL, 0.0)
    world.step(1000)  # 1 s of braking
    assert world.read_joint_states().velocity[0] == pytest.approx(0.0, abs=1.0)
    roll_braked, (x_braked, y_braked, _) = roll(world), world.link_pose("cube_body")[0]

    spin_roll, brake_roll = roll_spun - roll_rest, roll_braked - roll_spun
    spin_dy, brake_dy = y_spun - y_rest, y_braked - y_spun
    assert abs(brake_roll) > 0.3
    assert abs(brake_dy) > 0.05
    assert abs(x_braked - x_spun) < 0.2 * abs(brake_dy)
    # Spinning up and braking exert opposite reaction torques on the cube.
    assert abs(spin_roll) > 0.3 and math.copysign(1, spin_roll) == -math.copysign(1, brake_roll)
    assert abs(spin_dy) > 0.05 and abs(x_spun - x_rest) < 0.2 * abs(spin_dy)
    # Rolling (not sliding): a positive roll about +x carries the cube towards -y.
    assert math.copysign(1, brake_dy) == -math.copysign(1, brake_roll)


# -- 3. resets ------------------------------------------------------------------------------------
def test_reset_world_restores_pose_velocities_and_controllers(quiet_world):
    """reset_world: spawn pose at rest, command 0, time kept; reset_simulation also zeroes time."""
    world = quiet_world
    assert world.link_pose("cube_body") == (SPAWN, (0.0, 0.0, 0.0, 1.0))
    world.set_command(WHEEL, 100.0)
    world.step(500)
    assert world.link_pose("cube_body")[0] != pytest.approx(SPAWN, abs=1e-3)

    world.reset_world()
    position, orientation = world.link_pose("cube_body")
    assert position == pytest.approx(SPAWN, abs=1e-9)
    assert orientation == pytest.approx((0.0, 0.0, 0.0, 1.0), abs=1e-9)
    state = world.read_joint_states()
    assert state.position == (0.0,)
    assert state.velocity == (0.0,)
    assert state.effort == (0.0,)
    odometry = world.read_odometry(p3d(world))
    assert odometry.linear_velocity == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert odometry.angular_velocity == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert world.command(WHEEL) == 0.0
    assert world.step_count == 500
    assert world.time == pytest.approx(0.5)
    assert odometry.stamp == world.time

    world.set_command(WHEEL, 100.0)
    world.step(200)
    world.reset_simulation()
    assert world.step_count == 0
    assert world.time == 0.0
    assert world.command(WHEEL) == 0.0
    assert world.link_pose("cube_body")[0] == pytest.approx(SPAWN, abs=1e-9)
    assert world.read_joint_states().velocity == (0.0,)


def test_reset_world_is_deterministic(quiet_world):
    """The same command sequence after reset_world reproduces the first trajectory exactly."""
    world = quiet_world

    def run():
        trace = []
        for command in (0.0, 100.0, -100.0, 0.0):
            world.set_command(WHEEL, command)
            world.step(250)
            state = world.read_joint_states()
            trace.append((state.position, state.velocity, state.effort, world.link_pose("cube_body")))
        return trace

    first = run()
    world.reset_world()
    second = run()
    assert second == first
    assert first[-1][3] != (SPAWN, (0.0, 0.0, 0.0, 1.0))  # the cube did move


# -- 5. seeded noise ------------------------------------------------------------------------------
def odometry_stream(world, reads=20, every=20):
    sensor = p3d(world)
    stream = []
    for _ in range(reads):
        world.step(every)
        stream.append(world.read_odometry(sensor))
    return stream


def test_same_seed_gives_same_noise_and_different_seeds_differ(make_world):
    """Odometry noise is a function of the seed only."""
    a, b, c = make_world(seed=7), make_world(seed=7), make_world(seed=8)
    stream_a, stream_b, stream_c = odometry_stream(a), odometry_stream(b), odometry_stream(c)
    assert stream_a == stream_b
    assert all(ra.position != rc.position for ra, rc in zip(stream_a, stream_c))
    # The noise is there and has roughly the configured 0.01 standard deviation.
    errors = []
    for _ in range(20):
        a.step(20)
        truth = a.link_pose("cube_body")[0]
        errors.extend(m - t for m, t in zip(a.read_odometry(p3d(a)).position, truth))
    rms = math.sqrt(sum(e * e for e in errors) / len(errors))
    assert 0.005 < rms < 0.02


def test_reset_simulation_restarts_noise_stream(make_world):
    """After reset_simulation a World repeats the odometry stream of a fresh World with its seed."""
    world = make_world(seed=3)
    first = odometry_stream(world)
    world.reset_simulation()
    assert world.read_odometry(p3d(world)) == make_world(seed=3).read_odometry(p3d(world))
    world.reset_simulation()
    assert odometry_stream(world) == first == odometry_stream(make_world(seed=3))


# -- 6. non-finite commands -----------------------------------------------------------------------
@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf")])
def test_non_finite_command_is_ignored(world, bad):
    """set_command rejects NaN/inf, keeps the previous command, and the sim stays finite."""
    assert world.set_command(WHEEL, 20.0) is True
    assert world.set_command(WHEEL, bad) is False
    assert world.command(WHEEL) == 20.0
    world.step(200)
    state = world.read_joint_states()
    assert state.velocity[0] == pytest.approx(20.0, abs=1.0)
    assert all_finite(state.position + state.velocity + state.effort)
    odometry = world.read_odometry(p3d(world))
    assert all_finite(odometry.position + odometry.orientation + odometry.linear_velocity
                      + odometry.angular_velocity)
    position, orientation = world.link_pose("cube_body")
    assert all_finite(position + orientation)


# -- 7. bad construction input --------------------------------------------------------------------
@pytest.mark.parametrize("text", [
    "",
    "  \n\t ",
    "this is not <xml",
    '<?xml version="1.0"?><sdf version="1.6"><model name="cube"><link name="a"/></model></sdf>',
    '<robot><link name="a"/></robot>',  # no name attribute
], ids=["empty", "blank", "not-xml", "not-robot", "unnamed-robot"])
def test_bad_urdf_raises_urdf_error_naming_source(cube_params, text):
    config = parse_robot_config(cube_params)
    with pytest.raises(UrdfError) as info:
        World(text, config, urdf_source=SOURCE)
    assert SOURCE in str(info.value)


def test_controller_on_missing_joint(cube_params, cube_urdf):
    cube_params["controllers"][WHEEL]["joint"] = "no_such_joint"
    with pytest.raises(ConfigError) as info:
        World(cube_urdf, parse_robot_config(cube_params), urdf_source=SOURCE)
    message = str(info.value)
    assert "no_such_joint" in message and WHEEL in message and SOURCE in message


def test_sensor_on_missing_link(cube_params, cube_urdf):
    cube_params["sensors"][P3D]["link"] = "no_such_link"
    with pytest.raises(ConfigError) as info:
        World(cube_urdf, parse_robot_config(cube_params), urdf_source=SOURCE)
    message = str(info.value)
    assert "no_such_link" in message and P3D in message and SOURCE in message


@pytest.mark.parametrize("time_step", [0.0, -0.001, float("nan"), float("inf")])
def test_bad_time_step(cube_params, cube_urdf, time_step):
    with pytest.raises(ConfigError, match="time_step"):
        World(cube_urdf, parse_robot_config(cube_params), time_step=time_step)


# -- 8. odometry reading --------------------------------------------------------------------------
def test_odometry_reading_fields(world):
    """p3d odometry: world frame, cube_body child, stamped with sim time."""
    assert world.read_odometry(p3d(world)).stamp == 0.0
    world.step(37)
    reading = world.read_sensor(p3d(world))
    assert isinstance(reading, OdometryReading)
    assert reading.frame_id == "world"
    assert reading.child_frame_id == "cube_body"
    assert reading.stamp == world.time
    assert reading.stamp == pytest.approx(0.037)
    assert reading.position == pytest.approx(world.link_pose("cube_body")[0], abs=0.1)


# -- 9. replayed starts ---------------------------------------------------------------------------
@pytest.fixture(params=["cube", "hopper"])
def any_world(request, make_world):
    """Each robot as configured; the hopper's is built from hopper_description's files."""
    if request.param == "cube":
        return make_world()
    from hopper_training.robot import MONOPED
    config = parse_robot_config(yaml.safe_load(MONOPED.sim_config_path.read_text()))
    world = World(MONOPED.urdf_path.read_text(), config, time_step=TIME_STEP)
    request.addfinalizer(world.close)
    return world


def command_all(world, value):
    for name in world.controller_names:
        world.set_command(name, value)


def wander(world, seed):
    """An episode of varied commands, so that each start below follows a different history."""
    for k in range(6):
        command_all(world, (-1) ** k * (seed + k) * 0.2)
        world.step(80)


def raw_state(world):
    joints = world.read_joint_states()  # no noise on joint states
    return joints.position, joints.velocity, joints.effort, world.model_state()


def start(world, steps=150, batches=1):
    """reset_world, the start's commands, `steps` steps (replayed when the World can, else in `batches`
    calls of step), then 200 steps under other commands: whether it was replayed, the time the start took,
    and the states after it and after the 200 steps."""
    world.reset_world()
    command_all(world, 0.05)
    reset_time = world.time_ns
    replayed = world.replay_from_reset(steps)
    if not replayed:
        for _ in range(batches):
            world.step(steps // batches)
    after_start = (world.time_ns - reset_time, world.substeps, raw_state(world))
    command_all(world, -0.3)
    world.step(200)
    return replayed, after_start, raw_state(world)


def test_a_replayed_start_is_bit_for_bit_the_stepped_one(any_world):
    """The third same start after a reset is restored from memory and gives exactly the states, time and
    trajectory that stepping gave, whatever came before; the second, taken in batches as the sim node takes
    lockstep steps, is the one remembered."""
    world = any_world
    runs = []
    for seed, batches in ((1, 1), (2, 15), (3, 1), (4, 1)):
        wander(world, seed)
        runs.append(start(world, batches=batches))
    assert [replayed for replayed, _, _ in runs] == [False, False, True, True]
    assert all(run[1:] == runs[0][1:] for run in runs[1:])
    assert runs[0][1][0] == 150 * 1_000_000  # the start took 150 steps of sim time, replayed or not
    assert runs[0][2] != runs[0][1][2]  # the 200 steps after it moved the robot


def test_a_start_is_replayed_only_with_its_own_commands_and_steps(world):
    for _ in range(3):
        start(world)
    assert start(world)[0]
    assert not start(world, steps=140)[0]  # another number of steps
    world.reset_world()
    world.set_command(WHEEL, 7.0)  # another command
    assert not world.replay_from_reset(150)


def test_nothing_is_replayed_after_a_change_other_than_commands(world):
    for _ in range(3):
        start(world)
    world.reset_world()
    world.set_model_state(world.model_state())
    assert not world.replay_from_reset(150)
    world.step(10)
    assert not world.replay_from_reset(150)  # steps were taken since the reset


def test_a_start_with_a_command_changed_on_the_way_is_not_remembered(world):
    world.reset_world()
    world.replay_from_reset(150)
    world.reset_world()
    assert not world.replay_from_reset(150)  # seen twice: these steps would be remembered...
    world.step(100)
    world.set_command(WHEEL, 5.0)  # ...but a command changes before they end
    world.step(50)
    world.reset_world()
    assert not world.replay_from_reset(150)


def test_physics_changes_forget_every_start(world):
    for _ in range(3):
        start(world)
    world.set_gravity((0.0, 0.0, -3.0))
    stepped = start(world)
    assert not stepped[0]
    for _ in range(2):
        start(world)
    world.set_gravity((0.0, 0.0, -9.81))
    assert not start(world)[0]
    world.set_time_step(TIME_STEP)
    assert not start(world)[0]


def test_the_starts_remembered_are_bounded(world):
    from pybullet_sim.world import MAX_REMEMBERED_STARTS
    counts = range(10, 10 + MAX_REMEMBERED_STARTS + 1)
    for _ in range(2):
        for steps in counts:
            start(world, steps=steps)
    replayed = [start(world, steps=steps)[0] for steps in counts]
    assert replayed == [True] * MAX_REMEMBERED_STARTS + [False]


# -- 10. every change reaches the remembered starts -----------------------------------------------
# The World's public methods that change nothing the remembered starts depend on. replay_from_reset asks
# the memory itself, and close() ends the World. A new public method must be listed here or be marked
# with the kind of change it makes (pybullet_sim.world's _changes), which tells the memory of it.
READ_ONLY = {"command", "controller_running", "read_joint_states", "read_sensor", "read_odometry", "read_imu",
             "read_contact", "link_name", "entity_state", "link_state", "model_state", "link_pose", "render",
             "aim_gui_camera", "replay_from_reset", "close"}


def changing_calls(world):
    """An example call of every World method marked as changing it, by name."""
    return {"set_command": lambda: world.set_command(WHEEL, 0.05), "step": lambda: world.step(1),
            "start_controller": lambda: world.start_controller(WHEEL),
            "stop_controller": lambda: world.stop_controller(WHEEL),
            "set_gravity": lambda: world.set_gravity(world.gravity),
            "set_time_step": lambda: world.set_time_step(world.time_step),
            "set_solver": lambda: world.set_solver(world.solver),
            "set_attitude_assist": lambda: world.set_attitude_assist(*world.attitude_assist),
            "set_model_state": lambda: world.set_model_state(world.model_state()),
            "set_joint_positions": lambda: world.set_joint_positions({world.joint_names[0]: 0.1}),
            "reset_world": world.reset_world, "reset_simulation": world.reset_simulation}


def public_methods():
    return {name for name in dir(World) if not name.startswith("_") and inspect.isfunction(getattr(World, name))}


def test_every_public_method_is_read_only_or_marked_as_a_change():
    marked = {name for name in public_methods() if hasattr(getattr(World, name), "change")}
    assert public_methods() - marked == READ_ONLY
    assert not marked & READ_ONLY


def test_every_change_notifies_the_remembered_starts_with_its_kind(world, monkeypatch):
    told = []
    monkeypatch.setattr(world._starts, "changed", lambda kind, step_count: told.append(kind))
    calls = changing_calls(world)
    assert set(calls) == {name for name in public_methods() if hasattr(getattr(World, name), "change")}
    for name, call in calls.items():
        told.clear()
        call()
        assert getattr(World, name).change in told, name


@pytest.mark.parametrize("name, replayed", [
    ("set_command", True), ("start_controller", True), ("stop_controller", True),  # commands are in the key
    ("reset_world", True), ("reset_simulation", True),
    ("step", False), ("set_model_state", False), ("set_joint_positions", False), ("set_gravity", False),
    ("set_time_step", False), ("set_solver", False), ("set_attitude_assist", False)])
def test_a_change_after_a_reset_keeps_or_voids_the_start(world, name, replayed):
    for _ in range(3):
        start(world)
    world.reset_world()
    changing_calls(world)[name]()
    world.start_controller(WHEEL)  # running again, and the start's command
    command_all(world, 0.05)
    assert world.replay_from_reset(150) is replayed
