"""The ROS backends: lockstep over a running sim node's services (RosBackend), or stepped as the tutorials
step Gazebo (GazeboStyleBackend), and how a process becomes a ROS node.

The ROS backend is lockstep: one call of the sim's ~step_packed service carries the commands, advances
the paused sim exactly N physics steps and answers with every sensor's values at the new time (packed
as numbers and names; the sim also publishes them on the sensors' topics for any subscriber).
GazeboStyleBackend steps as the tutorials step Gazebo (unpause, publish, wait on /clock, pause, read
the latest messages), for comparison in ./ws bench. Only robot_rl.envs.backends.factory reaches this
module (by name), so that what runs without ROS never imports rospy.
"""
from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import rosgraph
import rospy
import yaml
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from gazebo_msgs.msg import ModelState
from gazebo_msgs.srv import GetModelState, GetPhysicsProperties, SetModelConfiguration, SetModelState
from pybullet_sim.config import parse_robot_config
from pybullet_sim.names import ATTITUDE_ASSIST_SERVICE, PHYSICS_SERVICE
from pybullet_sim.readings import FrameState
from pybullet_sim.ros import messages
from pybullet_sim.ros.client import (
    CommandPublisher,
    SensorSubscriber,
    SimConnection,
    SimConnectionError,
)
from pybullet_sim.ros.messages import SENSOR_MESSAGES
from pybullet_sim.sensors import unpack_readings
from pybullet_sim.srv import SetAttitudeAssist
from pybullet_sim.urdf import parse_urdf_joints

from .base import Backend, Readings, non_finite_problem

if TYPE_CHECKING:
    from ...task import RobotSpec

SIM_NODE = "/pybullet_sim"  # the sim node's name in every launch file: its private params describe the robot
STAMP_TOLERANCE_S = 1e-6  # a lockstep answer's stamp vs the one expected (the sim counts time in whole ns)


def init_ros_node(name: str) -> None:
    """Make this process an anonymous ROS node `name`, unless it already is one. Fails at once with a
    SimConnectionError when no master answers (rospy.init_node would retry forever)."""
    if rospy.core.is_initialized():
        return
    uri = rosgraph.get_master_uri()
    if not rosgraph.masterapi.is_online(uri):
        raise SimConnectionError(f"no ROS master at {uri} (ROS_MASTER_URI): start the sim's launch file, or "
                                 f"point ROS_MASTER_URI at the master it runs on")
    rospy.init_node(name, anonymous=True, disable_signals=threading.current_thread() is not threading.main_thread())


class RosBackend(Backend):
    """The robot behind a running sim node, in lockstep over ROS services.

    A step is one call of the sim's ~step_packed service: it carries the commands set since the last
    step, advances the paused sim, and answers with every sensor's values at the new time, packed as
    numbers and names (the values of the messages the sim publishes on the sensors' topics for any
    subscriber), so the env waits on one socket and never on a topic. Resets go through the sim's reset
    service, answered the same way.
    The robot (topics, controllers, sensors) is read from the sim node's own parameters, so the env
    and the sim cannot disagree; `robot` is the robot the caller expects, checked against them.
    Makes this process a ROS node (init_ros_node) if it is not one yet. Pauses the sim for lockstep;
    close() leaves it running again if it was running before.
    Every answer's stamp is checked against the sim the env started with: a step advances sim time by
    exactly its physics steps times the time step read at start, a reset_world keeps it, a
    reset_simulation restarts it at 0. A sim changed from outside (its time step set, or reset, by
    another node) raises a SimConnectionError saying what changed."""

    def __init__(self, robot: RobotSpec, timeout: float = 10.0, sim_node: str = SIM_NODE, hint: str | None = None):
        """`hint`: what to check when the sim does not answer (default: whether its launch file runs)."""
        init_ros_node("robot_rl_env")
        hint = hint or f"is the sim node running? (e.g. {robot.sim_launch})"
        self.timeout = timeout
        self.sim = SimConnection(timeout, hint)  # waits (bounded) for the sim node's services
        try:
            params = rospy.get_param(sim_node)
        except KeyError:
            raise SimConnectionError(f"parameter {sim_node} is missing: the sim node on this master "
                                     f"({rospy.get_master().getUri()[2]}) is not named {sim_node}") from None
        self.config = parse_robot_config(params, where=sim_node)
        expected = parse_robot_config(yaml.safe_load(robot.sim_config_path.read_text()), str(robot.sim_config_path))
        if self.config.robot_namespace != expected.robot_namespace:
            raise SimConnectionError(f"the sim node {sim_node} simulates {self.config.robot_namespace}, not "
                                     f"{expected.robot_namespace} ({robot.sim_config_path}): start {robot.sim_launch}")
        self.time_step = float(params.get("time_step", 0.001))
        self.gui = bool(params.get("gui", False))  # whether the sim node shows PyBullet's window
        self._controllers = {c.name for c in self.config.controllers}
        self._pending: dict[str, float] = {}  # commands for the next step
        self._sensor_names = [sensor.name for sensor in self.config.sensors]
        self._sensor_types = [sensor.type for sensor in self.config.sensors]
        self._was_running = not self.sim.is_paused()  # close() leaves the sim as it found it
        self.sim.pause()
        self._stamp: float | None = None  # sim time of the last answer: the next one is checked against it
        self._model_name = parse_urdf_joints(robot.urdf_path.read_text(encoding="utf-8"), str(robot.urdf_path))[0]
        self._placing: tuple[Any, Any] | None = None  # their service proxies, made by the first place()
        self._assist_found: tuple[float, float] | None = None  # the sim's attitude assist before the first set

    def _readings(self, packed: Any) -> Readings:
        """Readings from a pybullet_sim/PackedReadings answer."""
        try:
            joints, sensors = unpack_readings(packed.values, packed.names, self._sensor_types)
        except ValueError as error:
            raise SimConnectionError(f"the sim's answer does not fit the sensors {', '.join(self._sensor_names)}: "
                                     f"{error} (does the sim node run another version of pybullet_sim?)") from None
        readings = Readings(joints, dict(zip(self._sensor_names, sensors)))
        if not math.isfinite(sum(packed.values)):  # one sum: NaN or inf in, NaN or inf out (a huge sum: looked into)
            problem = non_finite_problem(readings)
            if problem:
                raise SimConnectionError(problem)
        return readings

    def reset(self, restart_time: bool = False) -> Readings:
        self._pending = {}  # a reset restarts the controllers, as in the World: earlier commands are gone
        readings = self._readings(self.sim.reset_packed(restart_time))
        expected = 0.0 if restart_time else self._stamp
        self._check_stamp(readings.stamp, expected, "reset_simulation (time back to 0)" if restart_time else
                          "reset_world (time goes on)")
        return readings

    def _check_stamp(self, stamp: float, expected: float | None, what: str) -> None:
        """SimConnectionError if the sim's answer to `what` is not stamped `expected` (None: not known yet)."""
        previous, self._stamp = self._stamp, stamp
        if expected is None or abs(stamp - expected) <= STAMP_TOLERANCE_S:
            return
        time_step = self._current_time_step()
        if time_step is not None and abs(time_step - self.time_step) > 1e-12:
            change = f"its time step is now {time_step:g} s, this env started with {self.time_step:g} s " \
                     f"(set_physics_properties called by another node?)"
        elif previous is not None and stamp < previous:
            change = f"its time went back from {previous:.6f} s to {stamp:.6f} s (reset by another node?)"
        else:
            change = f"after {what} its time is {stamp:.6f} s, expected {expected:.6f} s"
        raise SimConnectionError(f"the sim was changed from outside: {change}; every step must last the "
                              f"running_step the env started with: check what else talks to the sim node's "
                              f"services, and restart the sim")

    def _current_time_step(self) -> float | None:
        """The sim's time step now (Gazebo's get_physics_properties), or None if it does not answer."""
        proxy = rospy.ServiceProxy(PHYSICS_SERVICE, GetPhysicsProperties)
        try:
            return float(proxy().time_step)
        except (rospy.ServiceException, rospy.ROSException, OSError):
            return None
        finally:
            proxy.close()

    def set_command(self, controller: str, value: float) -> None:
        if controller not in self._controllers:
            raise KeyError(f"the robot has no controller {controller!r} (its controllers: "
                           f"{', '.join(sorted(self._controllers))})")
        self._pending[controller] = value

    def step(self, physics_steps: int) -> Readings:
        pending = self._pending
        self._pending = {}
        readings = self._readings(self.sim.step_packed(physics_steps, list(pending), list(pending.values())))
        expected = None if self._stamp is None else self._stamp + physics_steps * self.time_step
        self._check_stamp(readings.stamp, expected, f"a step of {physics_steps} physics steps")
        return readings

    def render(self, width: int, height: int) -> np.ndarray:
        return self.sim.render(width, height)

    def place(self, base: FrameState, joints: Mapping[str, float]) -> None:
        names = ("/gazebo/set_model_configuration", "/gazebo/set_model_state")
        if self._placing is None:
            for name in names:
                try:
                    rospy.wait_for_service(name, self.timeout)
                except rospy.ROSException:
                    raise SimConnectionError(f"service {name} is not available after {self.timeout} s: is the "
                                             f"sim node of this pybullet_sim version running?") from None
            self._placing = (rospy.ServiceProxy(names[0], SetModelConfiguration, persistent=True),
                             rospy.ServiceProxy(names[1], SetModelState, persistent=True))
        pose, twist = messages.pose_twist_msgs(base)
        requests = ((self._model_name, "", list(joints), list(joints.values())),
                    (ModelState(model_name=self._model_name, pose=pose, twist=twist, reference_frame="world"),))
        for name, proxy, request in zip(names, self._placing, requests, strict=True):
            try:
                answer = proxy(*request)
            except (rospy.ServiceException, rospy.ROSException) as error:
                raise SimConnectionError(f"service {name} failed: {error}") from None
            if not answer.success:
                raise SimConnectionError(f"service {name} refused the start pose: {answer.status_message}")

    def kick(self, velocity_change: tuple[float, float]) -> None:
        names = ("/gazebo/get_model_state", "/gazebo/set_model_state")
        try:
            for name in names:
                rospy.wait_for_service(name, self.timeout)
            now = rospy.ServiceProxy(names[0], GetModelState)(self._model_name, "world")
            now.twist.linear.x += velocity_change[0]
            now.twist.linear.y += velocity_change[1]
            answer = rospy.ServiceProxy(names[1], SetModelState)(
                ModelState(model_name=self._model_name, pose=now.pose, twist=now.twist, reference_frame="world"))
        except (rospy.ServiceException, rospy.ROSException) as error:
            raise SimConnectionError(f"a push: the sim's model state services failed: {error} (is the sim node "
                                     f"of this pybullet_sim version running?)") from None
        if not (now.success and answer.success):
            raise SimConnectionError(f"a push: the sim refused: {now.status_message} {answer.status_message}")

    def set_attitude_assist(self, stiffness: float, damping: float) -> None:
        try:
            rospy.wait_for_service(ATTITUDE_ASSIST_SERVICE, self.timeout)
            answer = rospy.ServiceProxy(ATTITUDE_ASSIST_SERVICE, SetAttitudeAssist)(stiffness, damping)
        except (rospy.ServiceException, rospy.ROSException) as error:
            raise SimConnectionError(f"service {ATTITUDE_ASSIST_SERVICE} failed: {error} (is the sim node of this "
                                     f"pybullet_sim version running?)") from None
        if not answer.success:
            raise ValueError(f"{ATTITUDE_ASSIST_SERVICE} refused: {answer.status_message}")
        if self._assist_found is None:
            self._assist_found = (answer.previous_stiffness, answer.previous_damping)

    def close(self) -> None:
        if self._assist_found is not None:  # the sim's assist as this env found it
            try:
                rospy.ServiceProxy(ATTITUDE_ASSIST_SERVICE, SetAttitudeAssist)(*self._assist_found)
            except (rospy.ServiceException, rospy.ROSException, OSError) as error:
                rospy.logwarn("could not put the sim's attitude assist back to %s: %s", self._assist_found, error)
        if self._placing is not None:
            for proxy in self._placing:
                proxy.close()
        if self._was_running:
            self.sim.unpause()
        self.sim.close()


class GazeboStyleBackend(RosBackend):
    """The robot behind a running sim node, stepped as The Construct's tutorials step Gazebo.

    A step unpauses the sim, publishes the commands set since the last step on the controllers' command
    topics, waits until /clock has advanced by the step's sim time (gazebo_ros throttles /clock to
    ~pub_clock_frequency of wall time, so the wait overshoots), pauses, and returns the latest message of
    every sensor's topic: readings of whatever time the sim published last, as in the tutorials. For
    comparing that step with the lockstep one (./ws bench); resets, render and close are RosBackend's."""

    def __init__(self, robot: RobotSpec, timeout: float = 10.0, sim_node: str = SIM_NODE):
        super().__init__(robot, timeout, sim_node)
        config, hint = self.config, f"is the sim node running? (e.g. {robot.sim_launch})"
        self._publishers = {c.name: CommandPublisher(config.command_topic(c), hint) for c in config.controllers}
        self._joints = SensorSubscriber(config.joint_states_topic, JointState, messages.joint_state_reading, hint)
        sides = {sensor.name: SENSOR_MESSAGES[sensor.type] for sensor in config.sensors}
        self._sensors = {s.name: SensorSubscriber(s.topic, sides[s.name].type, sides[s.name].to_reading, hint)
                         for s in config.sensors}
        for publisher in self._publishers.values():
            publisher.wait_for_subscriber(timeout)
        for subscriber in (self._joints, *self._sensors.values()):
            subscriber.wait_for_connection(timeout)
        self._clock = rospy.Time(0)
        self._clock_changed = threading.Condition()
        self._clock_subscriber = rospy.Subscriber("/clock", Clock, self._on_clock, tcp_nodelay=True)
        rospy.on_shutdown(self._wake)  # a stop (SIGTERM, Ctrl-C) ends a wait on /clock at once

    def _wake(self, *_: Any) -> None:
        with self._clock_changed:
            self._clock_changed.notify_all()

    def _on_clock(self, msg: Any) -> None:
        with self._clock_changed:
            self._clock = msg.clock
            self._clock_changed.notify_all()

    def step(self, physics_steps: int) -> Readings:
        with self._clock_changed:
            target = self._clock + rospy.Duration.from_sec(physics_steps * self.time_step)
        self.sim.unpause()
        pending, self._pending = self._pending, {}
        for controller, value in pending.items():
            self._publishers[controller].publish(value)
        with self._clock_changed:
            if not self._clock_changed.wait_for(lambda: self._clock >= target or rospy.is_shutdown(), self.timeout):
                raise SimConnectionError(f"/clock did not advance by {physics_steps} physics steps within "
                                         f"{self.timeout} s")
            if self._clock < target:
                raise SimConnectionError("shutdown while waiting for /clock")
        self.sim.pause()
        self._stamp = None  # the latest messages are of no exact time: the next answer is not checked
        readings = Readings(self._latest(self._joints), {name: self._latest(s) for name, s in self._sensors.items()})
        problem = non_finite_problem(readings)
        if problem:
            raise SimConnectionError(problem)
        return readings

    def _latest(self, subscriber: Any) -> Any:
        """The subscriber's latest reading; the first one waited for (bounded) if none has arrived yet."""
        latest = subscriber.latest
        return subscriber.wait_newer(0, self.timeout) if latest is None else latest

    def close(self) -> None:
        self._clock_subscriber.unregister()
        for publisher in self._publishers.values():
            publisher.unregister()
        for subscriber in (self._joints, *self._sensors.values()):
            subscriber.unregister()
        super().close()


def ros_backend(robot: RobotSpec, *, seed: int | None, timeout: float, gui: bool,
                hint: str | None = None) -> RosBackend:
    """The factory's "ros": the robot behind the running sim node (`seed` is the direct backend's; `hint`: what
    to check when the sim does not answer)."""
    backend = RosBackend(robot, timeout=timeout, hint=hint)
    if gui and not backend.gui:
        rospy.logwarn("render_mode 'human' over ROS: the robot shows in the sim node's window (launch the sim with "
                      "gui:=true) or in rviz (rviz:=true)")
    return backend
