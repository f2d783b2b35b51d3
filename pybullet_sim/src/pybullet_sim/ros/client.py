"""Client side of the sim: Gazebo's services, the lockstep step and reset (answered with every sensor's
message or its values), counted command publishers and sensor subscribers that wait (bounded) for fresh readings.

Every wait here has a timeout and fails with a SimConnectionError naming the topic or service and
what to check. Service proxies are persistent (one socket for the whole run): a sim node that dies, or
is restarted, ends the connection, and the error says which of the two happened.
"""
from __future__ import annotations

import http.client
import socket
import threading
import time
import warnings
import xmlrpc.client
from collections.abc import Callable, Iterable
from typing import Any, Generic, TypeVar

import numpy as np
import rosgraph
import rospy
from rospy.exceptions import TransportException
from std_msgs.msg import Float64
from std_srvs.srv import Empty

from gazebo_msgs.srv import GetPhysicsProperties
from pybullet_sim.msg import PackedReadings, Readings
from pybullet_sim.srv import (
    Render,
    RenderRequest,
    Reset,
    ResetRequest,
    Step,
    StepPacked,
    StepPackedRequest,
    StepRequest,
    StepResponse,
)

from ..names import GAZEBO_SERVICES, PHYSICS_SERVICE, RENDER_SERVICE, RESET_SERVICE, STEP_PACKED_SERVICE, STEP_SERVICE
from .messages import image_array

HINT = "is the sim node running? (e.g. roslaunch pybullet_sim cube_sim.launch)"
ANSWERED_WITH_AN_ERROR = "responded with an error"  # rospy's ServiceException text when the handler raised
LOST_SIM_WAIT = 2.0  # s a failed call looks for what became of the sim node (gone, or restarted)

Reading = TypeVar("Reading")


def synchronous_publisher(topic: str, msg_type, **kwargs) -> rospy.Publisher:
    """A publisher that writes to its subscribers' sockets in publish() itself (queue_size=None).

    In lockstep every message is awaited by a peer at once, and rospy's queued publishing adds a
    writer-thread hand-off and a sleep(0) to each publish (about 0.1 ms each, measured here).
    rospy warns about queue_size=None because a slow subscriber then blocks the publisher."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SyntaxWarning)
        return rospy.Publisher(topic, msg_type, queue_size=None, **kwargs)


class SimConnectionError(RuntimeError):
    """The simulator did not answer, or answered with an error; the message says where and why."""


class CommandPublisher:
    """A std_msgs/Float64 command publisher that counts what it sent, for the lockstep guarantee.

    rospy gives all publishers of one topic in a process one connection, and the sim counts what
    arrives per topic and node, so the count is kept per topic for the whole process."""

    _sent: dict[str, int] = {}
    _sent_lock = threading.Lock()

    def __init__(self, topic: str, hint: str = HINT):
        self.topic = rospy.resolve_name(topic)
        self.hint = hint
        self._publisher = synchronous_publisher(self.topic, Float64)

    @property
    def count(self) -> int:
        """Messages this process has published on the topic so far."""
        return CommandPublisher._sent.get(self.topic, 0)

    def wait_for_subscriber(self, timeout: float) -> None:
        """Block until the sim node subscribes (a message sent before that would be lost)."""
        end = time.monotonic() + timeout
        while self._publisher.get_num_connections() == 0:
            if rospy.is_shutdown():
                raise SimConnectionError(f"shutdown while waiting for a subscriber on {self.topic}")
            if time.monotonic() > end:
                raise SimConnectionError(f"nobody subscribed to {self.topic} within {timeout} s; {self.hint}")
            time.sleep(0.01)

    def publish(self, value: float) -> None:
        with CommandPublisher._sent_lock:
            try:
                self._publisher.publish(Float64(value))
            except rospy.ROSException as error:  # e.g. the node is shutting down: the topic is closed
                raise SimConnectionError(f"cannot publish on {self.topic}: {error}") from None
            CommandPublisher._sent[self.topic] = CommandPublisher._sent.get(self.topic, 0) + 1

    def unregister(self) -> None:
        self._publisher.unregister()


class SensorSubscriber(Generic[Reading]):
    """Keeps the latest message of a topic (converted to a reading) and lets callers wait for a newer one."""

    def __init__(self, topic: str, msg_type, to_reading: Callable[[object], Reading], hint: str = HINT):
        self.topic = rospy.resolve_name(topic)
        self.hint = hint
        self._to_reading = to_reading
        self._condition = threading.Condition()
        self._count = 0
        self._latest_msg: Any = None
        self._subscriber = rospy.Subscriber(self.topic, msg_type, self._callback, tcp_nodelay=True)
        rospy.on_shutdown(self._wake)

    def _wake(self) -> None:
        with self._condition:
            self._condition.notify_all()

    def _callback(self, msg) -> None:
        with self._condition:
            self._latest_msg = msg
            self._count += 1
            self._condition.notify_all()

    def wait_for_connection(self, timeout: float) -> None:
        """Block until a publisher of the topic is connected (messages sent before that are lost)."""
        end = time.monotonic() + timeout
        while self._subscriber.get_num_connections() == 0:
            if rospy.is_shutdown():
                raise SimConnectionError(f"shutdown while waiting for a publisher on {self.topic}")
            if time.monotonic() > end:
                raise SimConnectionError(f"no publisher of {self.topic} connected within {timeout} s; {self.hint}")
            time.sleep(0.01)

    @property
    def count(self) -> int:
        """How many messages have arrived; take it before a call, then wait_newer(count)."""
        return self._count

    @property
    def latest(self) -> Reading | None:
        msg = self._latest_msg
        return None if msg is None else self._to_reading(msg)

    def wait_newer(self, count: int, timeout: float, stamp: rospy.Time | None = None) -> Reading:
        """Wait for a message after the `count`-th (and stamped `stamp` if given); return its reading."""
        def arrived():
            return self._count > count and (stamp is None or self._latest_msg.header.stamp == stamp)
        with self._condition:
            if not self._condition.wait_for(lambda: arrived() or rospy.is_shutdown(), timeout) or not arrived():
                if rospy.is_shutdown():
                    raise SimConnectionError(f"shutdown while waiting for a message on {self.topic}")
                expected = f" stamped {stamp.to_sec():.6f} s" if stamp is not None else ""
                got = "" if self._latest_msg is None else \
                    f" (latest is stamped {self._latest_msg.header.stamp.to_sec():.6f} s)"
                raise SimConnectionError(f"no new message on {self.topic}{expected} within {timeout} s{got}; "
                                         f"{self.hint} Check `rostopic hz {self.topic}`.")
            return self._to_reading(self._latest_msg)

    def unregister(self) -> None:
        self._subscriber.unregister()


class CallWatchdog:
    """Bounds calls of persistent service proxies, which rospy cannot time out, without a thread
    hand-off per call: the caller notes when a call starts and ends (two attribute writes), and a
    daemon thread looks a few times per second; a call running longer than `timeout` gets its socket
    shut down, so that rospy raises and the caller can say which service did not answer. So does a call
    under way once a rospy shutdown is requested (SIGTERM, Ctrl-C: rospy leaves a service call waiting)."""

    def __init__(self, timeout: float):
        self.timeout = timeout
        self.expired: rospy.ServiceProxy | None = None   # the proxy whose call was ended, if any
        self._call: tuple[rospy.ServiceProxy, float] | None = None
        self._closed = threading.Event()
        threading.Thread(target=self._watch, name="service-call-watchdog", daemon=True).start()

    def start(self, proxy: rospy.ServiceProxy) -> None:
        self._call = (proxy, time.monotonic())

    def end(self) -> None:
        self._call = None

    def _watch(self) -> None:
        while not self._closed.wait(min(0.25, self.timeout / 4)):
            call = self._call
            if call is None or call[0].transport is None:
                continue
            stopped = rospy.core.is_shutdown_requested()
            if stopped or time.monotonic() - call[1] > self.timeout:
                self.expired = None if stopped else call[0]  # the caller names a late service, not a stop
                try:
                    call[0].transport.socket.shutdown(socket.SHUT_RDWR)
                except (AttributeError, OSError):  # already closed
                    pass

    def close(self) -> None:
        self._closed.set()


class _TimedTransport(xmlrpc.client.Transport):
    """XML-RPC over HTTP with a socket timeout (rosgraph's master proxy waits for ever)."""

    def __init__(self, timeout: float):
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        connection = super().make_connection(host)
        connection.timeout = self._timeout
        return connection


def service_provider(name: str, timeout: float) -> str | None:
    """The URI of the node serving `name` now (None: no node does), from the master, within `timeout` s;
    OSError (or an xmlrpc.client.Error) if the master does not answer."""
    master = xmlrpc.client.ServerProxy(rosgraph.get_master_uri(), transport=_TimedTransport(timeout))
    answer: Any = master.lookupService(rospy.get_name(), name)  # (code, status, uri); code 1: found
    return str(answer[2]) if answer[0] == 1 else None


def _accepts_connections(rosrpc_uri: str, timeout: float) -> bool:
    """Whether something listens at a service's rosrpc:// address (a killed node's port refuses)."""
    try:
        host, port = rospy.core.parse_rosrpc_uri(rosrpc_uri)
        socket.create_connection((host, port), timeout).close()
    except (OSError, rospy.ROSException):
        return False
    return True


class SimConnection:
    """pause / unpause / reset_world / reset_simulation / step / reset / is_paused on the sim node, every
    call bounded by `timeout` seconds of wall time."""

    def __init__(self, timeout: float = 10.0, hint: str = HINT):
        self.timeout = timeout
        self.hint = hint
        for name in GAZEBO_SERVICES + (STEP_SERVICE, STEP_PACKED_SERVICE, RESET_SERVICE, PHYSICS_SERVICE):
            try:
                rospy.wait_for_service(name, timeout)
            except rospy.ROSInterruptException:
                raise SimConnectionError(f"shutdown while waiting for service {name}") from None
            except rospy.ROSException:
                raise SimConnectionError(f"service {name} is not available after {timeout} s; {hint}") from None
        self._empty = {name: rospy.ServiceProxy(name, Empty, persistent=True) for name in GAZEBO_SERVICES}
        self._step = rospy.ServiceProxy(STEP_SERVICE, Step, persistent=True)
        self._step_packed = rospy.ServiceProxy(STEP_PACKED_SERVICE, StepPacked, persistent=True)
        self._packed_request = StepPackedRequest()
        self._reset = rospy.ServiceProxy(RESET_SERVICE, Reset, persistent=True)
        self._physics = rospy.ServiceProxy(PHYSICS_SERVICE, GetPhysicsProperties, persistent=True)
        self._request = StepRequest()
        self._render: rospy.ServiceProxy | None = None  # made on the first render()
        self._watchdog = CallWatchdog(timeout)
        try:  # which sim node this is: a restarted one serves its services at another address
            self._sim_uri = service_provider(STEP_PACKED_SERVICE, timeout)
        except (OSError, xmlrpc.client.Error):
            self._sim_uri = None
        self._lost: str | None = None  # why the sim node this connection was made with is lost (gone, restarted)

    def _failed(self, name: str, proxy: rospy.ServiceProxy, error: Exception) -> SimConnectionError:
        """The one-line error of a failed call. A connection that broke is dropped (rospy would send the next
        request on its closed socket: TransportTerminated, then an AttributeError); a sim that is gone or was
        restarted is remembered: every later call fails at once with the same line, never on another sim."""
        if ANSWERED_WITH_AN_ERROR not in str(error):  # the connection, not the request: the next call reconnects
            transport, proxy.transport = proxy.transport, None
            if transport is not None:
                transport.close()
        if self._watchdog.expired is proxy:
            return SimConnectionError(f"service {name} did not answer within {self.timeout} s: the sim node is "
                                      f"frozen or overloaded (is it stopped, or stepping a huge request?)")
        if rospy.core.is_shutdown_requested():  # a stop ended the call (CallWatchdog), or the sim with it
            return SimConnectionError(f"shutdown while waiting for service {name}")
        reason, lost = self._what_became_of_the_sim(error)
        if lost:
            self._lost = reason
        return SimConnectionError(f"service {name} failed: {reason}")

    def _what_became_of_the_sim(self, error: Exception) -> tuple[str, bool]:
        """After a call failed with `error`: whether the sim node is gone or was restarted, as the master tells
        (the reason, and whether the sim is lost to this connection). A dying node may still accept connections
        for a moment after its sockets broke: looked at again for up to LOST_SIM_WAIT seconds before the error
        is given as it is."""
        if ANSWERED_WITH_AN_ERROR in str(error):  # the sim is there: it refused the request
            return f"{error}; {self.hint}", False
        deadline = time.monotonic() + min(self.timeout, LOST_SIM_WAIT)
        while True:
            try:
                uri = service_provider(STEP_PACKED_SERVICE, min(self.timeout, LOST_SIM_WAIT))
            except (OSError, xmlrpc.client.Error):  # the master is gone too, or frozen: it cannot tell
                uri = self._sim_uri
            if uri is None or (uri == self._sim_uri and not _accepts_connections(uri, LOST_SIM_WAIT)):
                # a killed node stays registered with the master until another takes its name
                return (f"the sim node is gone (nothing serves {STEP_PACKED_SERVICE} any more: was it killed? see "
                        f"its log); {self.hint}"), True
            if self._sim_uri is not None and uri != self._sim_uri:
                return (f"the sim node was restarted (it serves {STEP_PACKED_SERVICE} at {uri} now, at "
                        f"{self._sim_uri} before): a restarted sim starts over (sim time 0, the robot at its spawn "
                        f"pose, its params read again), so this connection cannot go on with it; a new env connects "
                        f"to the new sim"), True
            if time.monotonic() > deadline:
                return f"{error}; {self.hint}", False
            time.sleep(0.05)

    def _call(self, name: str, proxy: rospy.ServiceProxy, request: Any = None) -> Any:
        if self._lost is not None:  # the sim this connection was made with is gone or was restarted
            raise SimConnectionError(f"service {name} failed: {self._lost}")
        self._watchdog.start(proxy)
        try:
            return proxy() if request is None else proxy(request)
        except (rospy.ServiceException, rospy.ROSException, TransportException) as error:
            raise self._failed(name, proxy, error) from None
        finally:
            self._watchdog.end()

    def _call_empty(self, name: str) -> None:
        self._call(name, self._empty[name])

    def is_paused(self) -> bool:
        """Whether physics is paused (Gazebo's get_physics_properties)."""
        return bool(self._call(PHYSICS_SERVICE, self._physics).pause)

    def pause(self) -> None:
        self._call_empty("/gazebo/pause_physics")

    def unpause(self) -> None:
        self._call_empty("/gazebo/unpause_physics")

    def reset_world(self) -> None:
        self._call_empty("/gazebo/reset_world")

    def reset_simulation(self) -> None:
        self._call_empty("/gazebo/reset_simulation")

    def step(self, steps: int, commands: Iterable[CommandPublisher] = ()) -> rospy.Time:
        """Advance the paused sim `steps` physics steps after it has received `commands`' messages.

        Returns the new sim time, which stamps every sensor message this step published."""
        request = self._request
        request.steps = steps
        request.command_topics = [c.topic for c in commands]
        request.command_counts = [c.count for c in commands]
        request.controllers, request.commands, request.return_readings = [], [], False
        return self._call(STEP_SERVICE, self._step, request).stamp

    def step_with(self, steps: int, controllers: list[str], values: list[float]) -> StepResponse:
        """Command `controllers` to `values`, advance the paused sim `steps` physics steps, and return the
        answer: the new sim time and every sensor's message of it (`readings`)."""
        request = self._request
        request.steps = steps
        request.command_topics, request.command_counts = [], []
        request.controllers, request.commands, request.return_readings = controllers, values, True
        return self._call(STEP_SERVICE, self._step, request)

    def step_packed(self, steps: int, controllers: list[str], values: list[float]) -> PackedReadings:
        """step_with() through ~step_packed: returns every sensor's values instead of its message (a
        PackedReadings, see pybullet_sim.sensors.unpack_readings; values[0] is the new sim time)."""
        request = self._packed_request
        request.steps, request.controllers, request.commands = steps, controllers, values
        return self._call(STEP_PACKED_SERVICE, self._step_packed, request).packed

    def reset(self, restart_time: bool) -> Readings:
        """Gazebo's reset_world (or with `restart_time` reset_simulation); returns every sensor's message after it."""
        return self._call(RESET_SERVICE, self._reset, ResetRequest(restart_time, False)).readings

    def reset_packed(self, restart_time: bool) -> PackedReadings:
        """reset(), answered with the sensors' values as a PackedReadings instead of their messages."""
        return self._call(RESET_SERVICE, self._reset, ResetRequest(restart_time, True)).packed

    def render(self, width: int, height: int) -> np.ndarray:
        """An RGB image (height x width x 3, uint8) of the robot from the sim's following camera."""
        if self._render is None:
            try:
                rospy.wait_for_service(RENDER_SERVICE, self.timeout)
            except rospy.ROSException:  # also on shutdown (ROSInterruptException)
                raise SimConnectionError(f"service {RENDER_SERVICE} is not available after {self.timeout} s; "
                                         f"{self.hint}") from None
            self._render = rospy.ServiceProxy(RENDER_SERVICE, Render, persistent=True)
        return image_array(self._call(RENDER_SERVICE, self._render, RenderRequest(width, height)).image)

    def close(self) -> None:
        self._watchdog.close()
        for proxy in (*self._empty.values(), self._step, self._step_packed, self._reset, self._physics,
                      *([self._render] if self._render else [])):
            proxy.close()

