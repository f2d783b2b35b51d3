"""ControllerManager: ros_control noetic's list/load/unload/switch semantics over a World (no ROS)."""
import copy

import pytest

from pybullet_sim.config import parse_robot_config
from pybullet_sim.controller_manager import (
    BEST_EFFORT,
    EFFORT_INTERFACE,
    JOINT_STATE_INTERFACE,
    STRICT,
    ControllerInfo,
    ControllerManager,
)
from pybullet_sim.world import World

WHEEL = "inertia_wheel_roll_joint_velocity_controller"
JSC = "joint_state_controller"


@pytest.fixture
def cube(cube_urdf, cube_params):
    world = World(cube_urdf, parse_robot_config(cube_params))
    yield world
    world.close()


@pytest.fixture
def manager(cube, cube_params):
    return ControllerManager(parse_robot_config(cube_params), cube)


def states(manager):
    return {info.name: info.state for info in manager.infos()}


def spin_wheel(world, speed=40.0):
    world.set_command(WHEEL, speed)
    world.step(300)
    return world.read_joint_states().velocity[0]


def test_everything_is_loaded_and_running_at_start(manager):
    assert manager.infos() == [
        ControllerInfo(JSC, "joint_state_controller/JointStateController", "running", JOINT_STATE_INTERFACE, ()),
        ControllerInfo(WHEEL, "effort_controllers/JointVelocityController", "running", EFFORT_INTERFACE,
                       ("inertia_wheel_roll_joint",)),
    ]
    assert manager.joint_states_running


def test_the_tutorials_reset_off_then_on_restarts_the_controllers(manager, cube):
    """ControllersConnection.reset_controllers: stop all, then start all, BEST_EFFORT."""
    assert spin_wheel(cube) == pytest.approx(40.0, abs=1.0)
    assert manager.switch([], [JSC, WHEEL], BEST_EFFORT) == (True, "")
    assert states(manager) == {JSC: "stopped", WHEEL: "stopped"}
    assert not manager.joint_states_running and not cube.controller_running(WHEEL)
    assert manager.switch([JSC, WHEEL], [], BEST_EFFORT) == (True, "")
    assert states(manager) == {JSC: "running", WHEEL: "running"}
    assert cube.command(WHEEL) == 0.0  # restarted: a velocity controller stops the joint
    cube.step(300)
    assert cube.read_joint_states().velocity[0] == pytest.approx(0.0, abs=1.0)


def test_best_effort_start_of_a_running_controller_restarts_it_unless_start_asap(manager, cube):
    """The tutorials' buggy reset (start_controllers twice, never stop): noetic restarts what is running."""
    spin_wheel(cube)
    assert manager.switch([WHEEL], [], BEST_EFFORT, start_asap=True) == (True, "")
    assert cube.command(WHEEL) == 40.0
    assert manager.switch([WHEEL], [], BEST_EFFORT) == (True, "")
    assert cube.command(WHEEL) == 0.0


def test_strict_refuses_unknown_names_and_changes_nothing(manager, cube):
    spin_wheel(cube)
    ok, message = manager.switch([], [WHEEL, "no_such_controller"], STRICT)
    assert not ok and "no_such_controller" in message and "STRICT" in message
    assert states(manager) == {JSC: "running", WHEEL: "running"}
    assert cube.controller_running(WHEEL) and cube.command(WHEEL) == 40.0


def test_best_effort_skips_unknown_names(manager):
    ok, message = manager.switch([], [WHEEL, "no_such_controller"], BEST_EFFORT)
    assert ok and "skipped" in message and "no_such_controller" in message
    assert states(manager)[WHEEL] == "stopped"


def test_stopping_a_stopped_controller(manager):
    manager.switch([], [WHEEL], STRICT)
    ok, message = manager.switch([], [WHEEL], STRICT)
    assert not ok and "not running" in message
    assert manager.switch([], [WHEEL], BEST_EFFORT).ok


def test_strict_start_of_a_running_controller_is_refused(manager, cube):
    spin_wheel(cube)
    ok, message = manager.switch([WHEEL], [], STRICT)
    assert not ok and "already running" in message
    assert cube.command(WHEEL) == 40.0


def test_one_controller_in_both_lists_is_refused(manager):
    for strictness in (BEST_EFFORT, STRICT):
        ok, message = manager.switch([WHEEL], [WHEEL], strictness)
        assert not ok and "both lists" in message
    assert states(manager)[WHEEL] == "running"


def test_strictness_zero_means_best_effort(manager):
    ok, message = manager.switch([], [WHEEL, "no_such_controller"], 0)
    assert ok and "BEST_EFFORT" in message
    assert states(manager)[WHEEL] == "stopped"


def test_load_and_unload(manager, cube):
    ok, message = manager.unload(WHEEL)
    assert not ok and "still running" in message
    assert not manager.load(WHEEL).ok  # already loaded
    assert manager.switch([], [WHEEL], STRICT).ok
    assert manager.unload(WHEEL) == (True, "")
    assert WHEEL not in states(manager)
    assert not manager.switch([WHEEL], [], STRICT).ok  # not loaded: unknown
    assert not manager.unload(WHEEL).ok
    cube.set_command(WHEEL, 40.0)  # an unloaded controller ignores commands and applies no effort
    cube.step(10)
    assert cube.read_joint_states().effort == (0.0,)
    assert manager.load(WHEEL) == (True, "")
    assert states(manager)[WHEEL] == "initialized"
    assert not cube.controller_running(WHEEL)
    assert manager.switch([WHEEL], [], STRICT).ok
    assert states(manager)[WHEEL] == "running" and cube.controller_running(WHEEL)


def test_loading_a_controller_the_configuration_lacks(manager):
    ok, message = manager.load("no_such_controller")
    assert not ok and "no_such_controller" in message and WHEEL in message


def test_two_controllers_on_one_joint_conflict(cube_urdf, cube_params):
    params = copy.deepcopy(cube_params)
    params["controllers"]["second_wheel_controller"] = copy.deepcopy(params["controllers"][WHEEL])
    config = parse_robot_config(params)
    world = World(cube_urdf, config)
    try:
        manager = ControllerManager(config, world)
        assert manager.switch([], ["second_wheel_controller"], STRICT).ok
        ok, message = manager.switch(["second_wheel_controller"], [], BEST_EFFORT)
        assert not ok and "inertia_wheel_roll_joint" in message
        assert manager.switch(["second_wheel_controller"], [WHEEL], STRICT).ok  # handing the joint over
    finally:
        world.close()


@pytest.mark.parametrize("strictness", [STRICT, BEST_EFFORT])
def test_a_huge_list_of_unknown_names_is_not_echoed_whole(manager, strictness):
    """A switch naming 100 000 unknown controllers (megabytes) answers with their count and the first three, and a
    name of a megabyte with its first 60 characters."""
    unknown = [f"no_such_controller_{i}" for i in range(100_000)]
    ok, message = manager.switch([], [WHEEL, *unknown], strictness)
    assert ok == (strictness == BEST_EFFORT) and len(message) < 500, len(message)
    assert "100000 names, the first 3: 'no_such_controller_0', 'no_such_controller_1', 'no_such_controller_2', ..." \
        in message
    ok, message = manager.load("x" * 10**6)
    assert not ok and len(message) < 500 and "(1000000 characters)" in message and WHEEL in message
