"""How a task env reaches its robot: over ROS (the product) or in-process (the speed reference).

Both backends expose the same three calls, each returning the same `Readings`:
`reset(restart_time)`, `set_command(controller, value)` + `step(physics_steps)`. The ROS backend
is lockstep: commands are published, one call to the sim's step service advances the paused sim
exactly N physics steps, and the backend waits (bounded) for every sensor stamped at the new time.
The direct backend makes the same calls on an in-process World and reads every sensor once per
call, as the sim node publishes them once, so the same seed and actions give the same readings.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Mapping, Optional

import yaml

from pybullet_sim.config import RobotConfig, parse_robot_config
from pybullet_sim.readings import JointStateReading

SIM_NODE = "/pybullet_sim"  # the sim node's name in every launch file: its private params describe the robot


@dataclass(frozen=True)
class Readings:
    """One snapshot of every sensor of the robot, all stamped at the same sim time."""

    joints: JointStateReading
    sensors: Mapping[str, object]  # sensor name (as in config/<robot>_sim.yaml) -> reading

    @property
    def stamp(self) -> float:
        return self.joints.stamp


class Backend(abc.ABC):
    """A robot and its sim, seen as readings and controller commands."""

    config: RobotConfig
    time_step: float

    @abc.abstractmethod
    def reset(self, restart_time: bool = False) -> Readings:
        """Robot back to its spawn pose, controllers restarted (Gazebo's reset_world); with
        restart_time also sim time and the sensor-noise generator (reset_simulation)."""

    @abc.abstractmethod
    def set_command(self, controller: str, value: float) -> None:
        """Command a controller; it takes effect from the next step."""

    @abc.abstractmethod
    def step(self, physics_steps: int) -> Readings:
        """Advance exactly `physics_steps` physics steps and return the readings at the new time."""

    def close(self) -> None:
        """Release the backend's resources."""


class DirectBackend(Backend):
    """The robot in an in-process World: no ROS, same readings."""

    def __init__(self, urdf_path: Path, sim_config_path: Path, time_step: float = 0.001, seed: int = 0):
        from pybullet_sim.world import World  # PyBullet only where it is used
        params = yaml.safe_load(Path(sim_config_path).read_text())
        self.config = parse_robot_config(params, where=str(sim_config_path))
        self.time_step = time_step
        self.world = World(Path(urdf_path).read_text(), self.config, time_step=time_step, seed=seed,
                           urdf_source=str(urdf_path))
        self._read()  # the sim node publishes every sensor once at start: keep the noise streams aligned

    def _read(self) -> Readings:
        world = self.world
        return Readings(world.read_joint_states(), {s.name: world.read_sensor(s) for s in self.config.sensors})

    def reset(self, restart_time: bool = False) -> Readings:
        if restart_time:
            self.world.reset_simulation()
        else:
            self.world.reset_world()
        return self._read()

    def set_command(self, controller: str, value: float) -> None:
        self.world.set_command(controller, value)

    def step(self, physics_steps: int) -> Readings:
        self.world.step(physics_steps)
        return self._read()

    def close(self) -> None:
        self.world.close()


class RosBackend(Backend):
    """The robot behind a running sim node, in lockstep over ROS topics and services.

    The robot (topics, controllers, sensors) is read from the sim node's own parameters, so the
    env and the sim cannot disagree. Needs rospy.init_node to have been called."""

    def __init__(self, timeout: float = 10.0, sim_node: str = SIM_NODE):
        import rospy
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import Imu, JointState

        from pybullet_sim import messages
        from pybullet_sim.client import CommandPublisher, SensorSubscriber, SimConnection, SimConnectionError
        from gazebo_msgs.msg import ContactsState

        self.timeout = timeout
        self.sim = SimConnection(timeout)  # waits (bounded) for the sim node's services
        try:
            params = rospy.get_param(sim_node)
        except KeyError:
            raise SimConnectionError(f"parameter {sim_node} is missing: the sim node on this master "
                                     f"({rospy.get_master().getUri()[2]}) is not named {sim_node}") from None
        self.config = parse_robot_config(params, where=sim_node)
        self.time_step = float(params.get("time_step", 0.001))
        self._commands: Dict[str, CommandPublisher] = {
            c.name: CommandPublisher(self.config.command_topic(c)) for c in self.config.controllers}
        kinds = {"p3d": (Odometry, messages.odometry_reading), "imu": (Imu, messages.imu_reading),
                 "contact": (ContactsState, messages.contact_reading)}
        self._joints = SensorSubscriber(self.config.joint_states_topic, JointState, messages.joint_state_reading)
        self._sensors = {s.name: SensorSubscriber(s.topic, *kinds[s.type]) for s in self.config.sensors}
        self._subscribers = [self._joints, *self._sensors.values()]
        for publisher in self._commands.values():
            publisher.wait_for_subscriber(timeout)
        for subscriber in self._subscribers:
            subscriber.wait_for_connection(timeout)
        self.sim.pause()

    def _wait(self, marks, stamp=None) -> Readings:
        joints = self._joints.wait_newer(marks[0], self.timeout, stamp)
        sensors = {name: subscriber.wait_newer(mark, self.timeout, stamp)
                   for (name, subscriber), mark in zip(self._sensors.items(), marks[1:])}
        return Readings(joints, sensors)

    def _marks(self):
        return [s.count for s in self._subscribers]

    def latest(self) -> Readings:
        """The last reading of every sensor, without waiting (the tutorials' way of reading)."""
        return Readings(self._joints.latest, {name: s.latest for name, s in self._sensors.items()})

    def reset(self, restart_time: bool = False) -> Readings:
        marks = self._marks()
        if restart_time:
            self.sim.reset_simulation()
        else:
            self.sim.reset_world()
        return self._wait(marks)

    def set_command(self, controller: str, value: float) -> None:
        self._commands[controller].publish(value)

    def step(self, physics_steps: int) -> Readings:
        marks = self._marks()
        stamp = self.sim.step(physics_steps, self._commands.values())
        return self._wait(marks, stamp)

    def close(self) -> None:
        for endpoint in (*self._commands.values(), *self._subscribers):
            endpoint.unregister()
        self.sim.close()


def make_backend(kind, urdf_path: Path, sim_config_path: Path, seed: Optional[int] = None,
                 timeout: float = 10.0) -> Backend:
    """`kind` "ros" (a sim node must be running), "direct" (an in-process World seeded with `seed`),
    or a Backend, returned as it is."""
    if isinstance(kind, Backend):
        return kind
    if kind == "ros":
        return RosBackend(timeout=timeout)
    if kind == "direct":
        return DirectBackend(urdf_path, sim_config_path, seed=seed or 0)
    raise ValueError(f"backend must be 'ros' or 'direct', got {kind!r}")
