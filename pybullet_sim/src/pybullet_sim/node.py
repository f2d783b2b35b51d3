"""The sim node: a thin ROS wrapper that stands in for Gazebo + gazebo_ros_control.

Params (private) -> a World; World readings -> messages; Gazebo's services -> World calls. The node
owns /clock (every node runs with use_sim_time). Two states as in Gazebo: running, where the main
loop advances physics at ~real_time_factor x wall time (0 = as fast as possible) and publishes each
sensor at its own rate of sim time, and paused, where time only moves through the lockstep service
~step (pybullet_sim/Step), which publishes every sensor once per call. ~render (pybullet_sim/Render)
answers an RGB image of the robot from the World's following camera.

Private params: ~time_step (0.001 s), ~real_time_factor (1.0), ~paused (false), ~gui (false), ~seed (0),
~command_timeout (2.0 s: how long ~step waits for the commands its caller announced),
~pub_clock_frequency (100 Hz of wall time at most for /clock, gazebo_ros's default), plus the robot's
controllers and sensors (see moving_cube_description/config/moving_cube_sim.yaml). The URDF comes from `robot_description`.
"""
from __future__ import annotations

import math
import sys
import threading
import time
from contextlib import contextmanager
from typing import Dict, List, Tuple

import rospy
import tf2_ros
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64
from std_srvs.srv import Empty, EmptyResponse

from pybullet_sim.msg import ContactsState
from pybullet_sim.srv import Render, RenderResponse, Step, StepResponse
from . import messages
from .client import RENDER_SERVICE, STEP_SERVICE, synchronous_publisher
from .config import ConfigError, SensorConfig, parse_robot_config
from .world import UrdfError, World

_SENSOR_MESSAGES = {"p3d": (Odometry, messages.odometry_msg), "imu": (Imu, messages.imu_msg),
                    "contact": (ContactsState, messages.contacts_msg)}


def _param(params: dict, key: str, kind, default, minimum=None):
    """A private param of a basic type, with a ConfigError naming it when it is mistyped."""
    value = params.get(key, default)
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise ConfigError(f"parameter ~{key} must be {kind.__name__}, got {value!r}")
    if kind is float and not math.isfinite(value):
        raise ConfigError(f"parameter ~{key} must be finite, got {value!r}")
    if minimum is not None and value < minimum:
        raise ConfigError(f"parameter ~{key} must be >= {minimum}, got {value!r}")
    return value


class _Schedule:
    """Publication times of one stream, in whole physics steps."""

    def __init__(self, rate: float, time_step: float):
        self.period = max(1, round(1.0 / (rate * time_step)))
        self.next_step = 0

    def due(self, step_count: int) -> bool:
        if step_count < self.next_step:
            return False
        self.next_step = step_count + self.period
        return True

    def restart(self, step_count: int) -> None:
        self.next_step = step_count + self.period


class SimNode:
    def __init__(self):
        params = rospy.get_param("~", {})
        self.time_step = _param(params, "time_step", float, 0.001, minimum=1e-6)
        self.real_time_factor = _param(params, "real_time_factor", float, 1.0, minimum=0.0)
        self._paused = _param(params, "paused", bool, False)
        self.command_timeout = _param(params, "command_timeout", float, 2.0, minimum=0.0)
        self.pub_clock_period = 1.0 / _param(params, "pub_clock_frequency", float, 100.0, minimum=1e-3)
        seed = _param(params, "seed", int, 0)
        gui = _param(params, "gui", bool, False)
        description_param = rospy.resolve_name("robot_description")
        if not rospy.has_param(description_param):
            raise ConfigError(f"parameter {description_param} is missing: load the robot's URDF into it "
                              f"(pybullet_sim's sim.launch does)")
        urdf = rospy.get_param(description_param)
        if not isinstance(urdf, str):
            raise UrdfError(f"parameter {description_param} must hold the URDF as a string")
        self.config = parse_robot_config(params, where=rospy.get_name())
        self.world = World(urdf, self.config, time_step=self.time_step, seed=seed, gui=gui,
                           urdf_source=f"parameter {description_param}")
        self._step_ns = round(self.time_step * 1e9)

        # One lock guards the World, with two conditions on it: `_run_state` wakes the main loop on
        # unpause, `_commands_arrived` wakes a step call waiting for its announced commands. Threads
        # other than the main loop announce themselves in _waiters so that the free-running loop steps
        # aside for them (Python locks are not fair).
        self._lock = threading.Lock()
        self._run_state = threading.Condition(self._lock)
        self._commands_arrived = threading.Condition(self._lock)
        self._waiters = 0
        self._waiters_lock = threading.Lock()  # `+=` on an attribute is not atomic across threads
        self._received: Dict[Tuple[str, str], int] = {}
        self._last_bad_command_warning = -math.inf

        # Synchronous publishers: in lockstep each message is awaited at once (see synchronous_publisher).
        self._clock_pub = synchronous_publisher("/clock", Clock)
        self._joint_pub = synchronous_publisher(self.config.joint_states_topic, JointState)
        self._sensor_pubs = [(sensor, synchronous_publisher(sensor.topic, _SENSOR_MESSAGES[sensor.type][0]),
                              _SENSOR_MESSAGES[sensor.type][1]) for sensor in self.config.sensors]
        self._tf = tf2_ros.TransformBroadcaster()
        self._last_clock_wall = -math.inf
        self._joint_schedule = _Schedule(self.config.joint_state_rate, self.time_step)
        self._sensor_schedules = [_Schedule(sensor.update_rate, self.time_step) for sensor in self.config.sensors]

        self._command_topics = {}
        for controller in self.config.controllers:
            topic = rospy.resolve_name(self.config.command_topic(controller))
            self._command_topics[topic] = controller.name
            rospy.Subscriber(topic, Float64, self._on_command, callback_args=topic, tcp_nodelay=True)
        rospy.Service("/gazebo/pause_physics", Empty, self._handle_pause)
        rospy.Service("/gazebo/unpause_physics", Empty, self._handle_unpause)
        rospy.Service("/gazebo/reset_simulation", Empty, self._handle_reset_simulation)
        rospy.Service("/gazebo/reset_world", Empty, self._handle_reset_world)
        rospy.Service(STEP_SERVICE, Step, self._handle_step)
        rospy.Service(RENDER_SERVICE, Render, self._handle_render)
        with self._lock:
            self._publish_all(force_clock=True)
        rospy.loginfo("pybullet_sim: %s loaded, time step %.4f s, %s, real_time_factor %.2f",
                      self.world.robot_name, self.time_step, "paused" if self._paused else "running",
                      self.real_time_factor)

    # -- helpers --------------------------------------------------------------------------------
    @contextmanager
    def _exclusive(self):
        """Hold the World lock from a callback thread, asking the free-running loop to step aside."""
        with self._waiters_lock:
            self._waiters += 1
        try:
            with self._lock:
                yield
        finally:
            with self._waiters_lock:
                self._waiters -= 1

    def _stamp(self) -> rospy.Time:
        nanoseconds = self.world.step_count * self._step_ns
        return rospy.Time(nanoseconds // 1_000_000_000, nanoseconds % 1_000_000_000)

    def _publish_joint_states(self, stamp):
        self._joint_pub.publish(messages.joint_state_msg(self.world.read_joint_states(), stamp))

    def _publish_sensor(self, sensor: SensorConfig, publisher, to_msg, stamp):
        publisher.publish(to_msg(self.world.read_sensor(sensor), stamp))
        if sensor.type == "p3d" and self._tf.pub_tf.get_num_connections():
            position, orientation = self.world.link_pose(sensor.link)
            self._tf.sendTransform(messages.transform_msg(sensor.frame_id, sensor.link, position, orientation, stamp))

    def _publish_clock(self, stamp, force: bool = False):
        """/clock at most ~pub_clock_frequency times per wall second, as gazebo_ros throttles it."""
        now = time.monotonic()
        if force or now - self._last_clock_wall >= self.pub_clock_period:
            self._last_clock_wall = now
            self._clock_pub.publish(Clock(clock=stamp))

    def _publish_all(self, force_clock: bool = False):
        """Publish every sensor once stamped now (after a lockstep step or a reset), and /clock if due."""
        stamp = self._stamp()
        self._publish_clock(stamp, force_clock)
        self._publish_joint_states(stamp)
        for sensor, publisher, to_msg in self._sensor_pubs:
            self._publish_sensor(sensor, publisher, to_msg, stamp)

    def _publish_due(self):
        """While running: publish what is due at the current step, each stream at its own rate."""
        count = self.world.step_count
        stamp = self._stamp()
        self._publish_clock(stamp)
        if self._joint_schedule.due(count):
            self._publish_joint_states(stamp)
        for (sensor, publisher, to_msg), schedule in zip(self._sensor_pubs, self._sensor_schedules):
            if schedule.due(count):
                self._publish_sensor(sensor, publisher, to_msg, stamp)

    def _restart_schedules(self):
        count = self.world.step_count
        for schedule in (self._joint_schedule, *self._sensor_schedules):
            schedule.restart(count)

    # -- callbacks ------------------------------------------------------------------------------
    def _on_command(self, msg: Float64, topic: str):
        caller = msg._connection_header.get("callerid", "") if hasattr(msg, "_connection_header") else ""
        with self._exclusive():
            if not self.world.set_command(self._command_topics[topic], msg.data):
                now = time.monotonic()
                if now - self._last_bad_command_warning > 5.0:
                    self._last_bad_command_warning = now
                    rospy.logwarn("pybullet_sim: ignored non-finite command %r on %s from %s (the command stays "
                                  "%g; this warning is throttled to one per 5 s)", msg.data, topic, caller,
                                  self.world.command(self._command_topics[topic]))
            key = (topic, caller)
            self._received[key] = self._received.get(key, 0) + 1
            self._commands_arrived.notify_all()

    def _handle_pause(self, _request):
        with self._exclusive():
            self._paused = True
        return EmptyResponse()

    def _handle_unpause(self, _request):
        with self._exclusive():
            if self._paused:
                # Streams resume one period after the last lockstep step published every sensor.
                self._restart_schedules()
            self._paused = False
            self._run_state.notify_all()
        return EmptyResponse()

    def _handle_reset_simulation(self, _request):
        with self._exclusive():
            self.world.reset_simulation()
            self._restart_schedules()
            self._publish_all(force_clock=True)
        return EmptyResponse()

    def _handle_reset_world(self, _request):
        with self._exclusive():
            self.world.reset_world()
            self._publish_all(force_clock=True)
        return EmptyResponse()

    def _handle_step(self, request):
        caller = request._connection_header.get("callerid", "")
        if request.steps == 0:
            raise rospy.ServiceException(f"{STEP_SERVICE}: steps must be >= 1 (got 0)")
        if len(request.command_topics) != len(request.command_counts):
            raise rospy.ServiceException(f"{STEP_SERVICE}: command_topics and command_counts differ in length")
        unknown = [t for t in request.command_topics if t not in self._command_topics]
        if unknown:
            raise rospy.ServiceException(f"{STEP_SERVICE}: no controller listens on {', '.join(unknown)} "
                                         f"(command topics: {', '.join(sorted(self._command_topics))})")
        announced = list(zip(request.command_topics, request.command_counts))
        with self._exclusive():
            if not self._paused:
                raise rospy.ServiceException(f"{STEP_SERVICE} refused: the simulation is running; call "
                                             f"/gazebo/pause_physics first (lockstep steps a paused simulation)")
            arrived = self._commands_arrived.wait_for(
                lambda: all(self._received.get((t, caller), 0) >= n for t, n in announced), self.command_timeout)
            if not arrived:
                missing = [f"{t} (announced {n}, received {self._received.get((t, caller), 0)})"
                           for t, n in announced if self._received.get((t, caller), 0) < n]
                raise rospy.ServiceException(
                    f"{STEP_SERVICE}: commands from {caller} did not arrive within {self.command_timeout} s on "
                    f"{'; '.join(missing)}; check that the publisher is connected to the sim node")
            self.world.step(request.steps)
            self._publish_all()
            return StepResponse(stamp=self._stamp())

    def _handle_render(self, request):
        with self._exclusive():
            try:
                rgb = self.world.render(request.width, request.height)
            except ValueError as error:
                raise rospy.ServiceException(f"{RENDER_SERVICE}: {error}") from None
            return RenderResponse(image=messages.image_msg(rgb, self._stamp()))

    # -- main loop ------------------------------------------------------------------------------
    def spin(self):
        """Advance physics while running, paced to real_time_factor; idle while paused."""
        origin = None  # (wall, sim) at which pacing restarted
        while not rospy.is_shutdown():
            if self._waiters:
                time.sleep(0.0002)
                continue
            with self._lock:
                if self._paused:
                    origin = None
                    self._run_state.wait(0.5)  # bounded so that shutdown is noticed
                    continue
                if origin is None:
                    origin = (time.monotonic(), self.world.time)
                self.world.step(1)
                self._publish_due()
                sim_elapsed = self.world.time - origin[1]
            if self.real_time_factor > 0.0:
                lag = origin[0] + sim_elapsed / self.real_time_factor - time.monotonic()
                if lag > 0.0:
                    time.sleep(lag)
                elif lag < -0.1:
                    origin = None  # cannot keep up: re-anchor instead of bursting to catch up

    def close(self):
        self.world.close()


def main(argv: List[str] = None) -> int:
    rospy.init_node("pybullet_sim", argv=argv)
    try:
        node = SimNode()
    except (ConfigError, UrdfError) as error:
        message = f"pybullet_sim cannot start: {error}"
        rospy.logfatal(message)
        print(message, file=sys.stderr, flush=True)
        return 1
    try:
        node.spin()
    finally:
        node.close()
    return 0
