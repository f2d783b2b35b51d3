"""Issue 14, item 4: wheel commands are clamped to the URDF limit, and the cube stays physical at every speed
within it. Before (commit a103b49) a 1.0e+300 command was accepted, and from about 400 rad/s the cube
gained energy from nowhere and was thrown kilometres (see SPIN_STEP_LIMIT in pybullet_sim/world.py)."""
import math
import xml.etree.ElementTree as ElementTree

import pybullet as p
import pytest

from pybullet_sim.config import parse_robot_config
from pybullet_sim.readings import FrameState
from pybullet_sim.world import World

WHEEL = "inertia_wheel_roll_joint_velocity_controller"
VELOCITY_LIMIT = 1000.0  # <limit velocity="1000"> of inertia_wheel_roll_joint


@pytest.fixture
def cube(cube_urdf, cube_params):
    world = World(cube_urdf, parse_robot_config(cube_params))
    yield world
    world.close()


@pytest.fixture
def inertials(cube_urdf):
    """Link name -> (mass, diagonal inertia) from the URDF; both inertial frames are the link frames."""
    links = {}
    for link in ElementTree.fromstring(cube_urdf).iter("link"):
        inertial = link.find("inertial")
        assert inertial.find("origin").get("xyz") == "0 0 0" and inertial.find("origin").get("rpy") == "0 0 0"
        tensor = inertial.find("inertia")
        links[link.get("name")] = (float(inertial.find("mass").get("value")),
                                   tuple(float(tensor.get(k)) for k in ("ixx", "iyy", "izz")))
    return links


def mechanical_energy(world, inertials):
    """Kinetic energy of both links plus their potential energy in the world's gravity."""
    energy = 0.0
    for link, (mass, inertia) in inertials.items():
        state = world.link_state(link)
        rotation = p.getMatrixFromQuaternion(state.orientation)  # row-major; columns are the link's axes
        body_rate = [sum(rotation[3 * row + col] * state.angular_velocity[row] for row in range(3)) for col in range(3)]
        energy += 0.5 * mass * sum(v * v for v in state.linear_velocity)
        energy += 0.5 * sum(i * w * w for i, w in zip(inertia, body_rate, strict=True))
        energy -= mass * sum(g * x for g, x in zip(world.gravity, state.position, strict=True))
    return energy


def centre_of_mass(world, inertials):
    total = sum(mass for mass, _ in inertials.values())
    return [sum(mass * world.link_state(link).position[k] for link, (mass, _) in inertials.items()) / total
            for k in range(3)]


@pytest.mark.parametrize("command, expected", [(1.0e300, VELOCITY_LIMIT), (-1.0e300, -VELOCITY_LIMIT),
                                               (1500.0, VELOCITY_LIMIT)])
def test_a_wheel_command_beyond_the_limit_is_clamped_to_it(cube, command, expected):
    assert cube.set_command(WHEEL, command) is True
    cube.step(1000)
    assert cube.read_joint_states().velocity[0] == pytest.approx(expected, abs=1.0)


@pytest.mark.parametrize("speed", [600.0, VELOCITY_LIMIT, -VELOCITY_LIMIT])
def test_the_cube_never_gains_more_energy_than_its_motor_gives(cube, inertials, speed):
    """3 s at a constant wheel command on the ground: mechanical energy - start <= the motor's work.

    Contacts only take energy away, so more energy than the motor's work is energy from nowhere. At
    commit a103b49 (no substeps) the energy from nowhere passes 0.5 J within 0.5 s at 600 and 1000 rad/s."""
    cube.step(200)  # resting on the ground
    start, work, farthest = mechanical_energy(cube, inertials), 0.0, 0.0
    cube.set_command(WHEEL, speed)
    for step in range(3000):
        before = cube.read_joint_states().velocity[0]
        cube.step()
        state = cube.read_joint_states()
        work += state.effort[0] * 0.5 * (before + state.velocity[0]) * cube.time_step
        if step % 10 == 9:
            excess = mechanical_energy(cube, inertials) - start - work
            assert excess < 0.5, f"{excess:.1f} J from nowhere after {cube.time:.3f} s at {speed} rad/s"
            farthest = max(farthest, math.hypot(*cube.model_state().position[:2]))
    assert abs(cube.read_joint_states().velocity[0]) == pytest.approx(abs(speed), abs=2.0)
    # The spin-up kick (200 N m on a 1 kg cube) tumbles it a few metres (15 m in 3 s at 1000 rad/s)
    assert farthest < 30.0


def test_a_floating_cube_keeps_its_centre_of_mass_at_full_wheel_speed(cube, inertials):
    """No gravity, no contact: internal torques cannot move the centre of mass (a103b49: 168 m in 2 s)."""
    cube.set_gravity((0.0, 0.0, 0.0))
    cube.set_model_state(FrameState((0.0, 0.0, 2.0), (0.0, 0.0, 0.0, 1.0), (0.0,) * 3, (0.0,) * 3))
    start = centre_of_mass(cube, inertials)
    cube.set_command(WHEEL, VELOCITY_LIMIT)
    for _ in range(20):
        cube.step(100)
        assert math.dist(centre_of_mass(cube, inertials), start) < 1e-3
    assert cube.read_joint_states().velocity[0] == pytest.approx(VELOCITY_LIMIT, abs=2.0)


def test_substeps_only_when_the_wheel_spins_fast(cube):
    """Ordinary speeds keep one PyBullet step per physics step, so their trajectories are unchanged."""
    cube.set_command(WHEEL, 100.0)  # the training's largest command
    for _ in range(300):
        cube.step()
        assert cube.substeps == 1
    cube.set_command(WHEEL, VELOCITY_LIMIT)
    cube.step(300)
    assert cube.substeps == 32
    cube.reset_world()
    cube.step()
    assert cube.substeps == 1
