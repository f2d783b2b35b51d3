"""The sim node: a thin ROS wrapper that stands in for Gazebo + gazebo_ros_control.

Params (private) -> a World; World readings -> messages; Gazebo's services -> World calls. The node
owns /clock (every node runs with use_sim_time). Two states as in Gazebo: running, where the main
loop advances physics at ~real_time_factor x wall time (0 = as fast as possible) and publishes each
sensor at its own rate of sim time, and paused, where time only moves through the lockstep service
~step (pybullet_sim/Step), which publishes every sensor once per call and can answer with those very
messages (pybullet_sim/Readings), so that a lockstep client needs one service call per step and no
subscription; ~step_packed (pybullet_sim/StepPacked) is the same step answered with the sensors' values
(pybullet_sim/PackedReadings) for clients that want readings; ~reset (pybullet_sim/Reset) is Gazebo's
reset_world or reset_simulation answered either way. ~render (pybullet_sim/Render) answers an RGB
image of the robot from the World's following camera. ~set_attitude_assist (pybullet_sim/SetAttitudeAssist) sets
the World's attitude assist, a torque that pulls the base upright (a training curriculum's; answered with the
gains it replaced).

Services, with Gazebo's names and types: /gazebo/{pause,unpause}_physics, reset_{simulation,world}
(std_srvs/Empty), /gazebo/{get,set}_physics_properties, get_world_properties, {get,set}_model_state,
get_link_state (gazebo_msgs; see physics_properties for what PyBullet honours), and ros_control's
<robot_namespace>/controller_manager/{switch,list,load,unload}_controller(s) (controller_manager_msgs;
see controller_manager), the last two groups served by pybullet_sim.ros.gazebo_services. Bad requests get
success false (ok false) and change nothing.

Private params: ~time_step (0.001 s), ~real_time_factor (1.0), ~paused (false), ~gui (false), ~seed (0),
~command_timeout (2.0 s: how long ~step waits for the commands its caller announced),
~pub_clock_frequency (100 Hz of wall time at most for /clock, gazebo_ros's default, but see TF_CLOCK_LAG_NS),
plus the robot's controllers and sensors (see moving_cube_description/config/moving_cube_sim.yaml). The URDF
comes from `robot_description`.
"""
from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from contextlib import contextmanager

import rospy
import tf2_ros
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Empty, EmptyResponse

from pybullet_sim.msg import PackedReadings, Readings
from pybullet_sim.srv import (
    Render,
    RenderResponse,
    Reset,
    ResetResponse,
    SetAttitudeAssist,
    SetAttitudeAssistResponse,
    Step,
    StepPacked,
    StepPackedResponse,
    StepRequest,
    StepResponse,
)

from ..config import SensorConfig, parse_robot_config
from ..controller_manager import ControllerManager
from ..errors import ConfigError, UrdfError
from ..names import ATTITUDE_ASSIST_SERVICE, RENDER_SERVICE, RESET_SERVICE, STEP_PACKED_SERVICE, STEP_SERVICE
from ..readings import JointStateReading
from ..sensors import SENSOR_KINDS, pack_readings
from ..validation import MAX_TIME_STEP, MAX_WAIT, param
from ..world import MIN_TIME_STEP, SolverSettings, World
from .client import synchronous_publisher
from .gazebo_services import GazeboServices
from .messages import SENSOR_MESSAGES, image_msg, joint_state_msg, transform_msg
from .shutdown import shutdown_on_signals, shutting_down

STEP_BATCH = 10  # physics steps between two looks at the clock during a lockstep call
# While /tf has subscribers, /clock goes out at least every this many ns of sim time, however fast the sim runs:
# robot_state_publisher skips a joint_states stamp within its publish interval (1/publish_frequency, 33 ms in
# sim.launch) of the older of its last publication and /clock, so with a lagging /clock it sends a reset's
# transforms again at the stamp it already sent (reset_world keeps time), and rviz warns TF_REPEATED_DATA.
TF_CLOCK_LAG_NS = 10_000_000
STEP_SLICE = 0.02  # s of wall time a lockstep call holds the World before it lets other services in
SHUTTING_DOWN = "the sim node is shutting down"


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
        time_step = param(params, "time_step", float, "~", 0.001, minimum=MIN_TIME_STEP, maximum=MAX_TIME_STEP)
        self.real_time_factor = param(params, "real_time_factor", float, "~", 1.0, minimum=0.0)
        self._paused = param(params, "paused", bool, "~", False)
        self.command_timeout = param(params, "command_timeout", float, "~", 2.0, minimum=0.0, maximum=MAX_WAIT)
        self.pub_clock_period = 1.0 / param(params, "pub_clock_frequency", float, "~", 100.0, minimum=1e-3)
        seed = param(params, "seed", int, "~", 0, minimum=0)  # numpy's seeds are >= 0; a ROS int is < 2**31
        gui = param(params, "gui", bool, "~", False)
        description_param = rospy.resolve_name("robot_description")
        if not rospy.has_param(description_param):
            raise ConfigError(f"parameter {description_param} is missing: load the robot's URDF into it "
                              f"(pybullet_sim's sim.launch does)")
        urdf = rospy.get_param(description_param)
        if not isinstance(urdf, str):
            raise UrdfError(f"parameter {description_param} must hold the URDF as a string")
        self.config = parse_robot_config(params, where=rospy.get_name())
        self.world = World(urdf, self.config, time_step=time_step, seed=seed, gui=gui,
                           urdf_source=f"parameter {description_param}")
        self.controllers = ControllerManager(self.config, self.world)
        self.gui = gui

        # One lock guards the World, with two conditions on it: `_run_state` wakes the main loop on
        # unpause, `_commands_arrived` wakes a step call waiting for its announced commands. Threads
        # other than the main loop announce themselves in _waiters so that the free-running loop steps
        # aside for them (Python locks are not fair).
        self._lock = threading.Lock()
        self._run_state = threading.Condition(self._lock)
        self._commands_arrived = threading.Condition(self._lock)
        self._waiters = 0
        self._waiters_lock = threading.Lock()  # `+=` on an attribute is not atomic across threads
        self._received: dict[tuple[str, str], int] = {}
        self._last_bad_command_warning = -math.inf

        # Synchronous publishers: in lockstep each message is awaited at once (see synchronous_publisher).
        self._clock_pub = synchronous_publisher("/clock", Clock)
        self._joint_pub = synchronous_publisher(self.config.joint_states_topic, JointState)
        sides = [SENSOR_MESSAGES[sensor.type] for sensor in self.config.sensors]
        self._sensor_pubs = [(sensor, synchronous_publisher(sensor.topic, side.type), side.to_message)
                             for sensor, side in zip(self.config.sensors, sides)]
        self._tf = tf2_ros.TransformBroadcaster()
        # A sensor's last /tf stamp: a reset (or a set_model_state) publishes at the time of the step before it,
        # and tf's listeners (rviz) warn TF_REPEATED_DATA on a second transform at one stamp; it is not resent.
        self._tf_stamps: dict[str, rospy.Time] = {}
        self._last_clock_wall = -math.inf
        self._last_clock_ns = 0
        self._pace_origin = None  # (wall, sim) at which the free-running loop's pacing restarted
        self._make_schedules()

        self._command_topics = {}
        self._controller_names = {controller.name for controller in self.config.controllers}
        for controller in self.config.controllers:
            topic = rospy.resolve_name(self.config.command_topic(controller))
            self._command_topics[topic] = controller.name
            rospy.Subscriber(topic, Float64, self._on_command, callback_args=topic, tcp_nodelay=True)
        rospy.Service("/gazebo/pause_physics", Empty, self._handle_pause)
        rospy.Service("/gazebo/unpause_physics", Empty, self._handle_unpause)
        rospy.Service("/gazebo/reset_simulation", Empty, self._handle_reset_simulation)
        rospy.Service("/gazebo/reset_world", Empty, self._handle_reset_world)
        rospy.Service(STEP_SERVICE, Step, self._handle_step)
        rospy.Service(STEP_PACKED_SERVICE, StepPacked, self._handle_step_packed)
        rospy.Service(RESET_SERVICE, Reset, self._handle_reset)
        self.gazebo_services = GazeboServices(self)
        rospy.Service(RENDER_SERVICE, Render, self._handle_render)
        rospy.Service(ATTITUDE_ASSIST_SERVICE, SetAttitudeAssist, self._handle_attitude_assist)
        rospy.on_shutdown(self._wake_main_loop)
        with self._lock:
            self._publish_all(self.stamp(), force_clock=True)
        rospy.loginfo("pybullet_sim: %s loaded, time step %.4f s, %s, real_time_factor %.2f",
                      self.world.robot_name, time_step, "paused" if self._paused else "running",
                      self.real_time_factor)

    # -- helpers --------------------------------------------------------------------------------
    @property
    def paused(self) -> bool:
        return self._paused

    def set_physics(self, time_step: float, gravity, solver: SolverSettings, real_time_factor: float) -> None:
        """Apply checked physics properties (Gazebo's set_physics_properties) from the next step on."""
        with self.exclusive():
            world = self.world
            if time_step != world.time_step:
                world.set_time_step(time_step)
                self._make_schedules()
            world.set_gravity(gravity)
            world.set_solver(solver)
            self.real_time_factor = real_time_factor
            self._pace_origin = None

    def _wake_main_loop(self) -> None:
        """On shutdown: the paused main loop ends now, not after its next timed wait."""
        with self._lock:
            self._run_state.notify_all()

    @contextmanager
    def exclusive(self):
        """Hold the World lock from a callback thread, asking the free-running loop to step aside. Once the
        node shuts down (its topics closing, then the World), a ServiceException says so: rospy answers the
        caller with it and logs it at debug level, where any other error would be logged with a traceback."""
        with self._waiters_lock:
            self._waiters += 1
        try:
            with self._lock:
                if shutting_down():
                    raise rospy.ServiceException(SHUTTING_DOWN)
                try:
                    yield
                except rospy.ServiceException:
                    raise
                except rospy.ROSException as error:  # publish() to a topic the shutdown closed
                    if not shutting_down():
                        raise
                    raise rospy.ServiceException(f"{SHUTTING_DOWN} ({error})") from None
        finally:
            with self._waiters_lock:
                self._waiters -= 1

    def stamp(self) -> rospy.Time:
        nanoseconds = self.world.time_ns
        return rospy.Time(nanoseconds // 1_000_000_000, nanoseconds % 1_000_000_000)

    def _publish_joint_states(self, stamp, message_wanted: bool) -> tuple[JointStateReading, JointState | None]:
        """Publish joint_states (a stopped joint_state_controller publishes nothing: then an empty reading
        and message). The message is built only for a subscriber or when `message_wanted`."""
        if not self.controllers.joint_states_running:
            msg = JointState()
            msg.header.stamp = stamp
            return JointStateReading(self.world.time, (), (), (), ()), msg
        reading = self.world.read_joint_states()
        if not (message_wanted or self._joint_pub.get_num_connections()):
            return reading, None
        msg = joint_state_msg(reading, stamp)
        self._joint_pub.publish(msg)
        return reading, msg

    def _publish_sensor(self, sensor: SensorConfig, publisher, to_msg, stamp, message_wanted: bool):
        """Read a sensor (always: its noise stream advances once per publication) and publish it; the message
        is built only for a subscriber or when `message_wanted`. Returns (reading, message or None)."""
        reading = self.world.read_sensor(sensor)
        msg = None
        if message_wanted or publisher.get_num_connections():
            msg = to_msg(reading, stamp)
            publisher.publish(msg)
        if (SENSOR_KINDS[sensor.type].broadcasts_pose and self._tf.pub_tf.get_num_connections()
                and self._tf_stamps.get(sensor.name) != stamp):
            self._tf_stamps[sensor.name] = stamp
            position, orientation = self.world.link_pose(sensor.link)
            self._tf.sendTransform(transform_msg(sensor.frame_id, sensor.link, position, orientation, stamp))
        return reading, msg

    def _publish_clock(self, stamp: rospy.Time, force: bool = False):
        """/clock at most ~pub_clock_frequency times per wall second, as gazebo_ros throttles it, except that
        while /tf has subscribers it never lags sim time by TF_CLOCK_LAG_NS or more."""
        now = time.monotonic()
        nanoseconds = stamp.to_nsec()
        if (force or now - self._last_clock_wall >= self.pub_clock_period
                or (nanoseconds - self._last_clock_ns >= TF_CLOCK_LAG_NS and self._tf.pub_tf.get_num_connections())):
            self._last_clock_wall, self._last_clock_ns = now, nanoseconds
            self._clock_pub.publish(Clock(clock=stamp))

    def _publish_all(self, stamp: rospy.Time, force_clock: bool = False,
                     answer: str | None = None) -> Readings | PackedReadings | None:
        """Publish every sensor once stamped `stamp`, the time now (after a lockstep step or a reset), and
        /clock if due. Returns, as `answer` asks, the messages published ("messages"), their values
        ("packed"), or None."""
        self._publish_clock(stamp, force_clock)
        wanted = answer == "messages"
        joints, joint_msg = self._publish_joint_states(stamp, wanted)
        published = [(sensor, *self._publish_sensor(sensor, publisher, to_msg, stamp, wanted))
                     for sensor, publisher, to_msg in self._sensor_pubs]
        if answer == "packed":
            return PackedReadings(*pack_readings(joints, [reading for _, reading, _ in published]))
        if answer != "messages":
            return None
        readings = Readings(joint_states=joint_msg)
        for sensor, _, msg in published:
            getattr(readings, SENSOR_KINDS[sensor.type].readings_field).append(msg)
        return readings

    def _publish_due(self):
        """While running: publish what is due at the current step, each stream at its own rate."""
        count = self.world.step_count
        stamp = self.stamp()
        self._publish_clock(stamp)
        if self._joint_schedule.due(count):
            self._publish_joint_states(stamp, False)
        for (sensor, publisher, to_msg), schedule in zip(self._sensor_pubs, self._sensor_schedules):
            if schedule.due(count):
                self._publish_sensor(sensor, publisher, to_msg, stamp, False)

    def _make_schedules(self):
        """Each stream's period in physics steps (again after the time step changes), from the next step."""
        self._joint_schedule = _Schedule(self.config.joint_state_rate, self.world.time_step)
        self._sensor_schedules = [_Schedule(sensor.update_rate, self.world.time_step) for sensor in self.config.sensors]
        self._restart_schedules()

    def _restart_schedules(self):
        count = self.world.step_count
        for schedule in (self._joint_schedule, *self._sensor_schedules):
            schedule.restart(count)

    def _step_world(self, service: str, steps: int) -> None:
        """Advance `steps` physics steps (World lock held), letting the other services in every STEP_SLICE; the
        first steps after a reset may be replayed from memory (World.replay_from_reset)."""
        if self.world.replay_from_reset(steps):
            return
        done, slice_end = 0, time.monotonic() + STEP_SLICE
        while done < steps:
            batch = min(STEP_BATCH, steps - done)
            self.world.step(batch)
            done += batch
            if done < steps and time.monotonic() >= slice_end:
                self._lock.release()
                try:
                    time.sleep(0.0005)  # Python locks are not fair: give the waiting callbacks the lock
                finally:
                    self._lock.acquire()
                if shutting_down():
                    raise rospy.ServiceException(f"{service} interrupted after {done} of {steps} steps: "
                                                 f"{SHUTTING_DOWN}")
                slice_end = time.monotonic() + STEP_SLICE

    def _command(self, controller: str, value: float, caller: str, via: str) -> None:
        """Command a controller (World lock held) from `caller` `via` a topic or service; a non-finite value
        is ignored with a throttled warning."""
        if not self.world.set_command(controller, value):
            now = time.monotonic()
            if now - self._last_bad_command_warning > 5.0:
                self._last_bad_command_warning = now
                rospy.logwarn("pybullet_sim: ignored non-finite command %r for %s on %s from %s (the command stays "
                              "%g; this warning is throttled to one per 5 s)", value, controller, via, caller,
                              self.world.command(controller))

    # -- callbacks ------------------------------------------------------------------------------
    def _on_command(self, msg: Float64, topic: str):
        caller = msg._connection_header.get("callerid", "") if hasattr(msg, "_connection_header") else ""
        try:
            with self.exclusive():
                self._command(self._command_topics[topic], msg.data, caller, topic)
                key = (topic, caller)
                self._received[key] = self._received.get(key, 0) + 1
                self._commands_arrived.notify_all()
        except rospy.ServiceException:  # shutting down: no step will use the command
            pass

    def _handle_pause(self, _request):
        with self.exclusive():
            self._paused = True
        return EmptyResponse()

    def _handle_unpause(self, _request):
        with self.exclusive():
            if self._paused:
                # Streams resume one period after the last lockstep step published every sensor.
                self._restart_schedules()
            self._paused = False
            self._run_state.notify_all()
        return EmptyResponse()

    def _handle_reset_simulation(self, _request):
        with self.exclusive():
            self.world.reset_simulation()
            self._restart_schedules()
            self._publish_all(self.stamp(), force_clock=True)
        return EmptyResponse()

    def _handle_reset_world(self, _request):
        with self.exclusive():
            self.world.reset_world()
            self._publish_all(self.stamp(), force_clock=True)
        return EmptyResponse()

    def _check_step(self, service: str, steps: int, controllers: Sequence[str], commands: Sequence[float]) -> None:
        """Refuse (ServiceException) a lockstep request's bad step count or commands; changes nothing."""
        if not 1 <= steps <= StepRequest.MAX_STEPS:
            raise rospy.ServiceException(f"{service}: steps must be between 1 and {StepRequest.MAX_STEPS} "
                                         f"(got {steps}); call it again for more")
        if len(controllers) != len(commands):
            raise rospy.ServiceException(f"{service}: controllers and commands differ in length")
        if not self._controller_names.issuperset(controllers):
            unknown = [c for c in controllers if c not in self._controller_names]
            raise rospy.ServiceException(f"{service}: no controller named {', '.join(unknown)} "
                                         f"(controllers: {', '.join(sorted(self._controller_names))})")

    def _lockstep(self, service: str, steps: int, controllers: Sequence[str], commands: Sequence[float], caller: str,
                  announced: list[tuple[str, int]]) -> rospy.Time:
        """(World lock held) Wait for the `announced` (topic, count) commands from `caller`, apply the
        request's commands, step; returns the new time."""
        if not self._paused:
            raise rospy.ServiceException(f"{service} refused: the simulation is running; call "
                                         f"/gazebo/pause_physics first (lockstep steps a paused simulation)")
        if announced and not self._commands_arrived.wait_for(
                lambda: all(self._received.get((t, caller), 0) >= n for t, n in announced), self.command_timeout):
            missing = [f"{t} (announced {n}, received {self._received.get((t, caller), 0)})"
                       for t, n in announced if self._received.get((t, caller), 0) < n]
            raise rospy.ServiceException(
                f"{service}: commands from {caller} did not arrive within {self.command_timeout} s on "
                f"{'; '.join(missing)}; check that the publisher is connected to the sim node")
        for controller, value in zip(controllers, commands):
            self._command(controller, value, caller, service)
        self._step_world(service, steps)
        return self.stamp()

    def _handle_step(self, request):
        caller = request._connection_header.get("callerid", "")
        self._check_step(STEP_SERVICE, request.steps, request.controllers, request.commands)
        if len(request.command_topics) != len(request.command_counts):
            raise rospy.ServiceException(f"{STEP_SERVICE}: command_topics and command_counts differ in length")
        unknown = [t for t in request.command_topics if t not in self._command_topics]
        if unknown:
            raise rospy.ServiceException(f"{STEP_SERVICE}: no controller listens on {', '.join(unknown)} "
                                         f"(command topics: {', '.join(sorted(self._command_topics))})")
        announced = list(zip(request.command_topics, request.command_counts))
        with self.exclusive():
            stamp = self._lockstep(STEP_SERVICE, request.steps, request.controllers, request.commands, caller,
                                   announced)
            if not request.return_readings:
                self._publish_all(stamp)
                return StepResponse(stamp=stamp)
            return StepResponse(stamp=stamp, readings=self._publish_all(stamp, answer="messages"))

    def _handle_step_packed(self, request):
        self._check_step(STEP_PACKED_SERVICE, request.steps, request.controllers, request.commands)
        with self.exclusive():
            stamp = self._lockstep(STEP_PACKED_SERVICE, request.steps, request.controllers, request.commands,
                                   request._connection_header.get("callerid", ""), [])
            return StepPackedResponse(self._publish_all(stamp, answer="packed"))

    def _handle_reset(self, request):
        with self.exclusive():
            if request.restart_time:
                self.world.reset_simulation()
                self._restart_schedules()
            else:
                self.world.reset_world()
            if request.packed:
                return ResetResponse(packed=self._publish_all(self.stamp(), force_clock=True, answer="packed"))
            return ResetResponse(readings=self._publish_all(self.stamp(), force_clock=True, answer="messages"))

    def _handle_render(self, request):
        with self.exclusive():
            try:
                rgb = self.world.render(request.width, request.height)
            except ValueError as error:
                raise rospy.ServiceException(f"{RENDER_SERVICE}: {error}") from None
            return RenderResponse(image=image_msg(rgb, self.stamp()))

    def _handle_attitude_assist(self, request):
        with self.exclusive():
            previous = self.world.attitude_assist
            try:
                self.world.set_attitude_assist(request.stiffness, request.damping)
            except ValueError as error:
                return SetAttitudeAssistResponse(False, str(error), *previous)
            return SetAttitudeAssistResponse(True, "", *previous)

    # -- main loop ------------------------------------------------------------------------------
    def spin(self):
        """Advance physics while running, paced to real_time_factor; idle while paused."""
        while not shutting_down():
            if self._waiters:
                time.sleep(0.0002)
                continue
            with self._lock:
                if self._paused:
                    self._pace_origin = None
                    self._run_state.wait(0.5)  # bounded so that shutdown is noticed
                    continue
                if self._pace_origin is None:
                    self._pace_origin = (time.monotonic(), self.world.time)
                origin, real_time_factor = self._pace_origin, self.real_time_factor
                self.world.step(1)
                try:
                    self._publish_due()
                except rospy.ROSException:  # publish() to a topic the shutdown closed
                    if shutting_down():
                        break
                    raise
                sim_elapsed = self.world.time - origin[1]
            if real_time_factor > 0.0:
                lag = origin[0] + sim_elapsed / real_time_factor - time.monotonic()
                if lag > 0.0:
                    time.sleep(lag)
                elif lag < -0.1:
                    with self._lock:  # cannot keep up: re-anchor instead of bursting to catch up
                        self._pace_origin = None

    def close(self):
        with self._lock:  # a lockstep call may be between two batches of steps
            self.world.close()


def main(argv: list[str] | None = None) -> int:
    rospy.init_node("pybullet_sim", argv=argv, disable_signals=True)
    shutdown_on_signals()  # the main loop holds the lock that the shutdown hook _wake_main_loop takes
    try:
        node = SimNode()
    except (ConfigError, UrdfError) as error:
        rospy.logfatal(f"pybullet_sim cannot start: {error}")
        return 1
    try:
        node.spin()
    finally:
        node.close()
    return 0
