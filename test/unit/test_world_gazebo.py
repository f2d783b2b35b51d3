"""World's side of Gazebo's physics and model services (no ROS): gravity, time step, solver settings,
model and link states, controller stop/start. The sim node maps the services onto exactly these calls."""
import copy
import math

import pytest
import yaml

from hopper_training.robot import MONOPED
from pybullet_sim.config import parse_robot_config
from pybullet_sim.readings import FrameState
from pybullet_sim.world import DEFAULT_GRAVITY, SolverSettings, World

HOPPER_URDF = MONOPED.urdf_path.read_text()
HOPPER_PARAMS = yaml.safe_load(MONOPED.sim_config_path.read_text())
WHEEL = "inertia_wheel_roll_joint_velocity_controller"
HFE = "hfe_joint_position_controller"
SPAWN = (0.0, 0.0, 0.11)


@pytest.fixture
def worlds():
    made = []

    def make(urdf, params, **kwargs):
        world = World(urdf, parse_robot_config(copy.deepcopy(params)), **kwargs)
        made.append(world)
        return world

    yield make
    for world in made:
        world.close()


@pytest.fixture
def cube(worlds, cube_urdf, cube_params):
    cube_params["sensors"]["p3d_base_controller"]["gaussian_noise"] = 0.0
    return worlds(cube_urdf, cube_params)


@pytest.fixture
def hopper(worlds):
    return worlds(HOPPER_URDF, HOPPER_PARAMS)


def base_z(world):
    return world.model_state().position[2]


# -- gravity --------------------------------------------------------------------------------------
def test_without_gravity_the_hopper_does_not_fall_and_gravity_survives_both_resets(hopper):
    """The tutorials' hopper reset: gravity 0, reset, gravity back. Spawned with its foot 5 cm up."""
    assert hopper.gravity == DEFAULT_GRAVITY
    hopper.set_gravity((0.0, 0.0, 0.0))
    hopper.step(500)
    assert base_z(hopper) == pytest.approx(1.0, abs=1e-6), "fell without gravity"
    for reset in (hopper.reset_world, hopper.reset_simulation):
        reset()
        assert hopper.gravity == (0.0, 0.0, 0.0)
        hopper.step(300)
        assert base_z(hopper) == pytest.approx(1.0, abs=1e-6), f"fell after {reset.__name__}"
    hopper.set_gravity(DEFAULT_GRAVITY)
    hopper.step(300)  # free fall of 5 cm takes 0.1 s, then it stands on its foot
    assert base_z(hopper) == pytest.approx(0.95, abs=0.02)


def test_imu_measures_the_gravity_in_force(hopper):
    hopper.set_gravity((0.0, 0.0, 0.0))
    hopper.step(2)
    (imu,) = [s for s in hopper.config.sensors if s.type == "imu"]
    assert hopper.read_imu(imu).linear_acceleration == pytest.approx((0.0, 0.0, 0.0), abs=1e-6)


@pytest.mark.parametrize("gravity", [(0.0, 0.0, float("nan")), (float("inf"), 0.0, 0.0), (0.0, 0.0)])
def test_bad_gravity_is_refused_and_changes_nothing(hopper, gravity):
    with pytest.raises(ValueError, match="gravity"):
        hopper.set_gravity(gravity)
    assert hopper.gravity == DEFAULT_GRAVITY
    hopper.step(150)
    assert base_z(hopper) < 0.99  # still falls


# -- time step ------------------------------------------------------------------------------------
def test_time_step_change_keeps_time_continuous_and_changes_the_physics_step(cube):
    cube.step(100)
    assert cube.time_ns == 100_000_000
    cube.set_time_step(0.002)
    cube.step(50)
    assert cube.time_ns == 200_000_000 and cube.time == pytest.approx(0.2)
    assert cube.step_count == 150
    # 50 steps of 2 ms move the spinning wheel as far as 100 steps of 1 ms
    cube.set_command(WHEEL, 10.0)
    cube.step(200)
    angle_2ms = cube.read_joint_states().position[0]
    assert cube.read_joint_states().velocity[0] == pytest.approx(10.0, abs=0.5)
    cube.reset_simulation()
    assert cube.time_step == 0.002 and cube.time_ns == 0  # reset_simulation keeps the step
    cube.set_time_step(0.001)
    cube.set_command(WHEEL, 10.0)
    cube.step(400)
    assert cube.read_joint_states().position[0] == pytest.approx(angle_2ms, rel=0.05)


@pytest.mark.parametrize("time_step", [0.0, -0.001, 1e-9, float("nan"), float("inf")])
def test_bad_time_step_is_refused_and_changes_nothing(cube, time_step):
    with pytest.raises(ValueError, match="time_step"):
        cube.set_time_step(time_step)
    assert cube.time_step == 0.001
    cube.step(10)
    assert cube.time_ns == 10_000_000


# -- solver settings ------------------------------------------------------------------------------
def test_solver_settings_are_applied_and_kept(cube):
    assert cube.solver == SolverSettings()
    settings = SolverSettings(iterations=20, residual_threshold=0.0, erp=0.3, cfm=1e-5)
    cube.set_solver(settings)
    cube.reset_simulation()
    assert cube.solver == settings
    cube.step(100)  # the cube still rests on the ground
    assert base_z(cube) == pytest.approx(0.1, abs=0.005)


@pytest.mark.parametrize("settings", [SolverSettings(iterations=0), SolverSettings(erp=1.5),
                                      SolverSettings(cfm=float("nan")), SolverSettings(residual_threshold=-1.0)],
                         ids=["no_iterations", "erp_above_1", "nan_cfm", "negative_threshold"])
def test_bad_solver_settings_are_refused(cube, settings):
    with pytest.raises(ValueError, match="solver"):
        cube.set_solver(settings)
    assert cube.solver == SolverSettings()


# -- model and link states ------------------------------------------------------------------------
def test_model_state_is_the_base_frame_and_link_state_the_link_frames(cube):
    state = cube.model_state()
    assert state == FrameState(SPAWN, (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert cube.link_names == ("cube_body", "inertia_wheel_roll")
    wheel = cube.link_state("inertia_wheel_roll")  # joint origin (0.1, 0, 0), rpy (0, 1.57, 0)
    assert wheel.position == pytest.approx((0.1, 0.0, 0.11), abs=1e-6)  # PyBullet: float precision
    assert wheel.orientation == pytest.approx((0.0, math.sin(0.785), 0.0, math.cos(0.785)), abs=1e-6)
    with pytest.raises(ValueError, match="no link 'no_such_link'.*cube_body"):
        cube.link_state("no_such_link")


def test_set_model_state_moves_the_cube_with_its_twist(cube):
    """Teleported 1 m along y, 0.5 m up, turned 90 deg about z and moving at 1 m/s along x."""
    half = math.sqrt(0.5)
    cube.set_model_state(FrameState((0.0, 1.0, 0.6), (0.0, 0.0, half, half), (1.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    state = cube.model_state()
    assert state.position == pytest.approx((0.0, 1.0, 0.6), abs=1e-9)
    assert state.orientation == pytest.approx((0.0, 0.0, half, half), abs=1e-9)
    assert state.linear_velocity == pytest.approx((1.0, 0.0, 0.0), abs=1e-9)
    # the wheel on the +x face now points along +y
    assert cube.link_state("inertia_wheel_roll").position == pytest.approx((0.0, 1.1, 0.6), abs=1e-6)
    cube.step(100)  # 0.1 s of free flight
    state = cube.model_state()
    assert state.position[0] == pytest.approx(0.1, abs=1e-3)
    assert state.position[2] == pytest.approx(0.6 - 0.5 * 9.81 * 0.1 ** 2, abs=2e-3)
    assert state.linear_velocity[2] == pytest.approx(-0.981, abs=0.01)


def test_set_model_state_normalises_the_quaternion_as_gazebo_does(cube):
    cube.set_model_state(FrameState((0.0, 0.0, 0.5), (0.0, 0.0, 0.0, 0.0), (0.0,) * 3, (0.0,) * 3))
    assert cube.model_state().orientation == pytest.approx((0.0, 0.0, 0.0, 1.0))
    cube.set_model_state(FrameState((0.0, 0.0, 0.5), (0.0, 0.0, 0.0, 2.0), (0.0,) * 3, (0.0,) * 3))
    assert cube.model_state().orientation == pytest.approx((0.0, 0.0, 0.0, 1.0))


@pytest.mark.parametrize("state", [
    FrameState((float("nan"), 0.0, 0.5), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3, (0.0,) * 3),
    FrameState((0.0, 0.0, 0.5), (0.0, 0.0, 0.0, float("inf")), (0.0,) * 3, (0.0,) * 3),
    FrameState((0.0, 0.0, 0.5), (0.0, 0.0, 0.0, 1.0), (0.0, float("nan"), 0.0), (0.0,) * 3),
], ids=["nan_position", "inf_orientation", "nan_twist"])
def test_non_finite_model_state_is_refused_and_changes_nothing(cube, state):
    before = cube.model_state()
    with pytest.raises(ValueError, match="finite"):
        cube.set_model_state(state)
    assert cube.model_state() == before


def test_set_joint_positions_puts_joints_at_rest_and_keeps_the_base_and_commands(worlds):
    """Gazebo's set_model_configuration: the monoped's crouched start."""
    hopper = worlds(HOPPER_URDF, HOPPER_PARAMS)
    hopper.set_command(HFE, 0.3)
    hopper.step(100)
    base = hopper.model_state().position
    hopper.set_joint_positions({"kfe_joint": -0.9, "hfe_joint": 0.476})
    joints = hopper.read_joint_states()
    positions = dict(zip(joints.name, joints.position))
    assert (positions["haa_joint"], positions["hfe_joint"], positions["kfe_joint"]) == \
        pytest.approx((0.0, 0.476, -0.9), abs=1e-9)
    assert dict(zip(joints.name, joints.velocity))["hfe_joint"] == 0.0
    assert hopper.model_state().position == pytest.approx(base) and hopper.command(HFE) == 0.3


@pytest.mark.parametrize("positions, message", [
    ({"kfe_joint": -0.5, "foot": 0.0}, "no movable joint 'foot'"),
    ({"kfe_joint": -0.5, "hfe_joint": math.nan}, "finite"),
    ({"kfe_joint": -0.5, "hfe_joint": 1e30}, r"'hfe_joint': position 1e\+30 is outside its URDF limits \[-1.6, 1.6\]"),
    ({"kfe_joint": 0.1}, r"outside its URDF limits \[-1.6, 0.0\]"),
])
def test_bad_joint_positions_are_refused_and_change_nothing(worlds, positions, message):
    hopper = worlds(HOPPER_URDF, HOPPER_PARAMS)
    before = hopper.read_joint_states().position
    with pytest.raises(ValueError, match=message):
        hopper.set_joint_positions(positions)
    assert hopper.read_joint_states().position == before


# -- controllers stop and start -------------------------------------------------------------------
def test_a_stopped_wheel_controller_lets_the_wheel_coast(cube):
    cube.set_command(WHEEL, 50.0)
    cube.step(300)
    assert cube.read_joint_states().velocity[0] == pytest.approx(50.0, abs=1.0)
    cube.stop_controller(WHEEL)
    assert not cube.controller_running(WHEEL)
    assert cube.set_command(WHEEL, -50.0) is True  # accepted, and ignored
    cube.step(300)
    state = cube.read_joint_states()
    assert state.effort == (0.0,)
    # No effort: the wheel keeps turning (the cube rocks a little, nothing brakes the joint)
    assert state.velocity[0] == pytest.approx(50.0, abs=2.0)
    cube.reset_world()  # a reset restarts running controllers only
    assert not cube.controller_running(WHEEL)


def test_starting_restarts_a_velocity_controller_at_zero(cube):
    cube.set_command(WHEEL, 50.0)
    cube.step(300)
    cube.stop_controller(WHEEL)
    cube.start_controller(WHEEL)
    assert cube.command(WHEEL) == 0.0
    cube.step(300)
    assert cube.read_joint_states().velocity[0] == pytest.approx(0.0, abs=1.0)


def test_starting_a_position_controller_holds_the_current_position(hopper):
    hopper.set_command(HFE, 0.5)
    hopper.step(400)
    hopper.stop_controller(HFE)
    hopper.step(50)
    position = hopper.read_joint_states().position[1]
    hopper.start_controller(HFE)
    assert hopper.command(HFE) == pytest.approx(position)
