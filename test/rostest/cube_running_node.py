#!/usr/bin/env python3
"""rostest node: the running sim as a Gazebo-era client sees it (topics, rates, pause, a wheel command)."""
import math
import threading
import unittest

import rosgraph
import rospy
import rostest
import tf2_ros
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Empty
from tf.transformations import euler_from_quaternion

WHEEL_COMMAND = "/moving_cube/inertia_wheel_roll_joint_velocity_controller/command"
TIMEOUT = 10.0


class Recorder:
    """Keeps every message of a topic; lets the test wait (bounded) for a condition on them."""

    def __init__(self, topic, msg_type):
        self.topic = topic
        self.messages = []
        self.condition = threading.Condition()
        rospy.Subscriber(topic, msg_type, self._callback)

    def _callback(self, msg):
        with self.condition:
            self.messages.append(msg)
            self.condition.notify_all()

    def wait_until(self, predicate, timeout, what):
        with self.condition:
            if not self.condition.wait_for(lambda: bool(self.messages) and predicate(self.messages), timeout):
                raise AssertionError(f"{self.topic}: {what} did not happen within {timeout} s")
            return self.messages[-1]

    def holds_for(self, predicate, timeout):
        """True if predicate stays false for the whole timeout (used to check that nothing happens)."""
        with self.condition:
            return not self.condition.wait_for(lambda: predicate(self.messages), timeout)


def stamp(msg):
    return msg.clock.to_sec() if isinstance(msg, Clock) else msg.header.stamp.to_sec()


def span(messages):
    return stamp(messages[-1]) - stamp(messages[0])


class CubeRunningTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("cube_running_test")
        cls.joints = Recorder("/moving_cube/joint_states", JointState)
        cls.odom = Recorder("/moving_cube/odom", Odometry)
        cls.clock = Recorder("/clock", Clock)
        for name in ("/gazebo/pause_physics", "/gazebo/unpause_physics"):
            rospy.wait_for_service(name, TIMEOUT)
        cls.pause = rospy.ServiceProxy("/gazebo/pause_physics", Empty)
        cls.unpause = rospy.ServiceProxy("/gazebo/unpause_physics", Empty)

    def test_topics_have_the_tutorial_names_and_types(self):
        self.odom.wait_until(lambda m: True, TIMEOUT, "a first odom message")
        published = dict(rospy.get_published_topics())
        self.assertEqual(published.get("/moving_cube/joint_states"), "sensor_msgs/JointState")
        self.assertEqual(published.get("/moving_cube/odom"), "nav_msgs/Odometry")
        self.assertEqual(published.get("/clock"), "rosgraph_msgs/Clock")
        self.assertEqual(published.get("/tf"), "tf2_msgs/TFMessage")
        _, subscribers, services = rosgraph.Master("/cube_running_test").getSystemState()
        self.assertIn("/pybullet_sim", dict(subscribers).get(WHEEL_COMMAND, []))
        for service in ("/gazebo/pause_physics", "/gazebo/unpause_physics", "/gazebo/reset_simulation",
                        "/gazebo/reset_world", "/pybullet_sim/step"):
            self.assertIn(service, dict(services))

    def test_frames(self):
        odom = self.odom.wait_until(lambda m: True, TIMEOUT, "a first odom message")
        self.assertEqual((odom.header.frame_id, odom.child_frame_id), ("world", "cube_body"))
        joints = self.joints.wait_until(lambda m: True, TIMEOUT, "a first joint_states message")
        self.assertEqual(joints.name, ["inertia_wheel_roll_joint"])
        buffer = tf2_ros.Buffer()
        tf2_ros.TransformListener(buffer)
        world_to_cube = buffer.lookup_transform("world", "cube_body", rospy.Time(0), rospy.Duration(TIMEOUT))
        self.assertEqual(world_to_cube.child_frame_id, "cube_body")
        self.assertGreater(world_to_cube.transform.translation.z, 0.05, "the cube's centre is above the ground")
        wheel = buffer.lookup_transform("cube_body", "inertia_wheel_roll", rospy.Time(0), rospy.Duration(TIMEOUT))
        self.assertAlmostEqual(wheel.transform.translation.x, 0.1, delta=1e-6)

    def test_rates_in_sim_time(self):
        for recorder, rate in ((self.joints, 30.0), (self.odom, 50.0)):
            recent: list = []

            def three_seconds(messages, recent=recent):
                recent[:] = [m for m in messages if stamp(m) >= stamp(messages[-1]) - 3.0]
                return span(recent) >= 2.9

            recorder.wait_until(three_seconds, TIMEOUT, "3 s of sim time")
            measured = (len(recent) - 1) / span(recent)
            self.assertAlmostEqual(measured, rate, delta=0.2 * rate, msg=f"{recorder.topic} at {measured:.1f} Hz")

    def test_pause_stops_the_clock_and_unpause_resumes_it(self):
        self.clock.wait_until(lambda m: True, TIMEOUT, "a first /clock message")
        self.pause()
        try:
            paused_at = stamp(self.clock.messages[-1])
            # Running at real time, 1 s of wall time would add about 1 s of sim time.
            self.assertTrue(self.clock.holds_for(lambda m: stamp(m[-1]) > paused_at + 0.05, 1.0),
                            "/clock kept advancing after /gazebo/pause_physics")
        finally:
            self.unpause()
        self.clock.wait_until(lambda m: stamp(m[-1]) > paused_at + 0.2, TIMEOUT, "/clock advancing after unpause")

    def test_a_gazebo_era_client_moves_the_cube(self):
        """What seed 000's CubeRLUtils does: publish wheel speeds, watch joint_states and odom."""
        publisher = rospy.Publisher(WHEEL_COMMAND, Float64, queue_size=1)
        self.odom.wait_until(lambda m: publisher.get_num_connections() > 0, TIMEOUT, "the sim subscribing")
        start = self.odom.messages[-1].pose.pose.position
        publisher.publish(Float64(80.0))
        self.joints.wait_until(lambda m: m[-1].velocity[0] > 75.0, TIMEOUT, "the wheel reaching 80 rad/s")
        publisher.publish(Float64(-80.0))
        self.joints.wait_until(lambda m: m[-1].velocity[0] < -75.0, TIMEOUT, "the wheel reaching -80 rad/s")

        def rolled(messages):
            o = messages[-1].pose.pose
            roll = euler_from_quaternion([o.orientation.x, o.orientation.y, o.orientation.z, o.orientation.w])[0]
            return abs(roll) > 0.3 and abs(o.position.y - start.y) > 0.05
        self.odom.wait_until(rolled, TIMEOUT, "the cube rolling about x and moving along y")

        publisher.publish(Float64(float("nan")))
        publisher.publish(Float64(0.0))
        last = self.joints.wait_until(lambda m: abs(m[-1].velocity[0]) < 1.0, TIMEOUT, "the wheel stopping")
        self.assertTrue(all(math.isfinite(v) for v in last.position + last.velocity + last.effort))
        o = self.odom.messages[-1].pose.pose
        self.assertTrue(all(math.isfinite(v) for v in (o.position.x, o.position.y, o.position.z, o.orientation.w)))


if __name__ == "__main__":
    rostest.rosrun("workspace_tests", "cube_running", CubeRunningTest)
