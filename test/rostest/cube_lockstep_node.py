#!/usr/bin/env python3
"""rostest node: the lockstep step service, Gazebo's resets, and the command ordering guarantee."""
import math
import threading
import time
import unittest

import rospy
import rostest
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from pybullet_sim.ros import messages
from pybullet_sim.ros.client import CommandPublisher, SensorSubscriber, SimConnection, SimConnectionError
from pybullet_sim.sensors import unpack_readings
from pybullet_sim.srv import StepRequest

WHEEL_CONTROLLER = "inertia_wheel_roll_joint_velocity_controller"
WHEEL_COMMAND = f"/moving_cube/{WHEEL_CONTROLLER}/command"
TIMEOUT = 5.0
EFFORT_LIMIT = 200.0  # URDF effort limit of inertia_wheel_roll_joint
P_GAIN = 1.0          # config/moving_cube_sim.yaml


class CubeLockstepTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("cube_lockstep_test")
        cls.sim = SimConnection(timeout=TIMEOUT)
        cls.wheel = CommandPublisher(WHEEL_COMMAND)
        cls.wheel.wait_for_subscriber(TIMEOUT)
        cls.joints = SensorSubscriber("/moving_cube/joint_states", JointState, messages.joint_state_reading)
        cls.odom = SensorSubscriber("/moving_cube/odom", Odometry, messages.odometry_reading)
        cls.clock = SensorSubscriber("/clock", Clock, lambda msg: msg.clock)
        for subscriber in (cls.joints, cls.odom, cls.clock):
            subscriber.wait_for_connection(TIMEOUT)

    def setUp(self):
        self.sim.pause()
        mark = self.odom.count
        self.sim.reset_simulation()
        self.odom.wait_newer(mark, TIMEOUT)

    def step(self, steps=1):
        """One lockstep step: returns the joint and odom readings stamped at the new time."""
        joints_mark, odom_mark = self.joints.count, self.odom.count
        stamp = self.sim.step(steps, [self.wheel])
        return (stamp, self.joints.wait_newer(joints_mark, TIMEOUT, stamp),
                self.odom.wait_newer(odom_mark, TIMEOUT, stamp))

    def lockstep_calls(self):
        """~step and ~step_packed, each as a call of a step count (the two refuse bad requests alike)."""
        return {"/pybullet_sim/step": self.sim.step,
                "/pybullet_sim/step_packed": lambda steps: self.sim.step_packed(steps, [], [])}

    def test_step_is_refused_while_running(self):
        self.sim.unpause()
        try:
            for service, call in self.lockstep_calls().items():
                with self.assertRaisesRegex(SimConnectionError, f"{service} refused: .*running.*pause_physics"):
                    call(1)
        finally:
            self.sim.pause()

    def test_step_of_zero_is_refused(self):
        for service, call in self.lockstep_calls().items():
            with self.assertRaisesRegex(SimConnectionError, f"{service}: steps must be between 1 and 100000"):
                call(0)

    def test_step_beyond_the_maximum_is_refused(self):
        """Step.srv's MAX_STEPS (100 s of sim time at 1 ms): more is refused and nothing moves."""
        before = self.step(1)[0]
        for service, call in self.lockstep_calls().items():
            for steps in (StepRequest.MAX_STEPS + 1, 1_000_000_000):
                expected = f"{service}: steps must be between 1 and {StepRequest.MAX_STEPS} \\(got {steps}\\)"
                with self.assertRaisesRegex(SimConnectionError, expected):
                    call(steps)
        self.assertEqual(self.step(1)[0], before + rospy.Duration(0, 1_000_000))

    def test_step_packed_answers_the_values_of_exactly_n_steps_later(self):
        """~step_packed: the commands in the request, exactly n physics steps, the joint's values at the new time."""
        self.step(300)  # landed
        packed = self.sim.step_packed(40, [WHEEL_CONTROLLER], [50.0])
        joints, (odom,) = unpack_readings(packed.values, packed.names, ["p3d"])
        self.assertAlmostEqual(joints.stamp, 0.34, places=9)
        self.assertEqual(odom.stamp, joints.stamp)
        self.assertGreater(joints.velocity[0], 1.0, "the wheel should spin up towards the commanded 50 rad/s")
        stamp, _, _ = self.step(1)
        self.assertEqual(stamp, rospy.Time(0, 341_000_000))

    def test_step_advances_exactly_n_physics_steps(self):
        stamp, joints, odom = self.step(40)
        self.assertEqual(stamp, rospy.Time(0, 40_000_000))
        self.assertEqual(joints.stamp, 0.04)
        stamp, _, _ = self.step(7)
        self.assertEqual(stamp, rospy.Time(0, 47_000_000))

    def test_each_step_applies_the_command_published_before_it(self):
        """1000 publish-then-step cycles: the effort of each step is the PID of that step's command.

        With p = 1 and one physics step per call, the velocity controller's effort is
        clamp(command - velocity before the step), so the effort in joint_states proves which command
        the step used."""
        mark = self.joints.count
        self.sim.reset_world()
        velocity = self.joints.wait_newer(mark, TIMEOUT).velocity[0]
        for k in range(1000):
            command = (60.0 if k % 2 == 0 else -60.0) + (k % 7)
            self.wheel.publish(command)
            _, joints, _ = self.step(1)
            expected = max(-EFFORT_LIMIT, min(EFFORT_LIMIT, P_GAIN * (command - velocity)))
            self.assertEqual(joints.effort[0], expected, f"cycle {k}: command {command} was not applied")
            velocity = joints.velocity[0]

    def test_reset_simulation_brings_time_and_pose_back(self):
        _, _, moved = self.roll_the_cube()
        odom_mark, clock_mark = self.odom.count, self.clock.count
        self.sim.reset_simulation()
        odom = self.odom.wait_newer(odom_mark, TIMEOUT)
        self.assertEqual(odom.stamp, 0.0)
        self.assertEqual(self.clock.wait_newer(clock_mark, TIMEOUT), rospy.Time(0))
        self.assert_at_spawn(odom)

    def test_reset_world_brings_pose_back_while_time_keeps_going(self):
        stamp, _, moved = self.roll_the_cube()
        odom_mark, joints_mark = self.odom.count, self.joints.count
        self.sim.reset_world()
        odom = self.odom.wait_newer(odom_mark, TIMEOUT)
        joints = self.joints.wait_newer(joints_mark, TIMEOUT)
        self.assertEqual(odom.stamp, stamp.to_sec())
        self.assert_at_spawn(odom)
        self.assertEqual(joints.velocity[0], 0.0)
        next_stamp, _, _ = self.step(1)
        self.assertEqual(next_stamp, stamp + rospy.Duration(0, 1_000_000))

    def test_clock_keeps_up_with_lockstep_while_tf_is_listened_to(self):
        """robot_state_publisher skips a joint_states stamp within 1/publish_frequency of the older of its last
        publication and /clock: with /clock throttled to 100 per wall second and lockstep far faster than real
        time, it sent a reset's transforms again at the stamp it had sent (reset_world keeps time), and rviz
        warned TF_REPEATED_DATA (test_display.py). While /tf has subscribers, /clock never lags sim time by 10 ms."""
        clocks, frames = [], set()
        arrived = threading.Condition()

        def on_clock(msg):
            with arrived:
                clocks.append(msg.clock)
                arrived.notify_all()

        def on_tf(msg):
            with arrived:
                frames.update(transform.child_frame_id for transform in msg.transforms)

        tf_subscriber = rospy.Subscriber("/tf", TFMessage, on_tf, queue_size=None, tcp_nodelay=True)
        # rospy gives a node one connection per topic, and its own /clock subscriber (use_sim_time) made it at
        # init_node with queue_size 1 (rospy/impl/simtime.py); the connection keeps the size it was made with
        # (rospy/impl/tcpros_pubsub.py), so on a loaded machine all but the last of the /clock messages read at
        # once were dropped here (gaps of 20-30 ms seen). Unbounded, the connection keeps every one.
        clock_subscriber = rospy.Subscriber("/clock", Clock, on_clock, queue_size=10_000, tcp_nodelay=True)
        try:
            self.assertTrue(clock_subscriber.impl.connections, "no /clock connection: is the sim publishing /clock?")
            for connection in clock_subscriber.impl.connections:
                connection.protocol.queue_size = None
            deadline = time.monotonic() + TIMEOUT
            while "cube_body" not in frames:  # the sim sends it once it sees /tf's subscriber: this one
                self.assertLess(time.monotonic(), deadline, "no /tf of cube_body after lockstep steps: the sim "
                                "node should broadcast the odometry's frame while /tf has a subscriber")
                self.step(1)
            with arrived:
                del clocks[:]
            for _ in range(20):
                for _ in range(10):
                    stamp = self.sim.step(5, [])
                self.sim.reset_world()
            with arrived:
                self.assertTrue(arrived.wait_for(lambda: clocks and clocks[-1] >= stamp, TIMEOUT),
                                f"/clock did not reach the last step's stamp {stamp.to_sec()} s")
                gaps = [(later - earlier).to_sec() for earlier, later in zip(clocks, clocks[1:])]
        finally:
            tf_subscriber.unregister()
            clock_subscriber.unregister()
        self.assertLessEqual(max(gaps), 0.010, f"/clock lagged sim time by {max(gaps):.3f} s")

    def roll_the_cube(self):
        """Let the cube land, then spin the wheel up: the reaction rolls the cube along y."""
        self.step(300)
        self.wheel.publish(100.0)
        stamp, joints, odom = self.step(300)
        self.assertGreater(abs(odom.position[1]), 0.05, "spinning the wheel up should roll the cube along y")
        return stamp, joints, odom

    def assert_at_spawn(self, odom):
        noise = 0.05  # five sigma of the p3d noise
        for actual, spawn in zip(odom.position, (0.0, 0.0, 0.11)):
            self.assertAlmostEqual(actual, spawn, delta=noise)
        self.assertAlmostEqual(abs(odom.orientation[3]), 1.0, delta=noise)
        self.assertTrue(all(math.isfinite(v) for v in odom.linear_velocity))


if __name__ == "__main__":
    rostest.rosrun("workspace_tests", "cube_lockstep", CubeLockstepTest)
