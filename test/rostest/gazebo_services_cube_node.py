#!/usr/bin/env python3
"""rostest node: the cube tutorial's Gazebo-style client code against the sim, and Gazebo's model services.

The tutorial's cube env (openai_ros RobotGazeboEnv + CubeSingleDiskEnv) constructs a GazeboConnection and a
ControllersConnection, resets with the controllers switched off and on around reset_simulation, and steps
by unpause, publish, wait for the wheel speed, pause. Our own clients (workspace_tools.gazebo_style) do the
same here; set_model_state must move the cube, a stopped wheel controller must let the wheel coast, and
max_update_rate must set the real-time factor."""
import math
import time
import unittest

import rospy
import rostest
from geometry_msgs.msg import Pose, Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from controller_manager_msgs.srv import SwitchController, SwitchControllerRequest
from gazebo_msgs.msg import ModelState
from gazebo_msgs.srv import GetLinkState, GetModelState, GetPhysicsProperties, GetWorldProperties, SetModelState
from pybullet_sim.ros.client import CommandPublisher, SensorSubscriber, SimConnection
from workspace_tools.gazebo_style import ControllersConnection, GazeboConnection

TIMEOUT = 10.0
CONTROLLERS = ["joint_state_controller", "inertia_wheel_roll_joint_velocity_controller"]
WHEEL_COMMAND = "/moving_cube/inertia_wheel_roll_joint_velocity_controller/command"
SPAWN = (0.0, 0.0, 0.11)
NOISE = 0.05  # five sigma of the p3d noise


def raw(msg):
    return msg


class CubeGazeboServicesTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("gazebo_services_cube_test")
        cls.gazebo = GazeboConnection()
        cls.controllers = ControllersConnection("moving_cube", CONTROLLERS)
        cls.sim = SimConnection(timeout=TIMEOUT)
        cls.wheel = CommandPublisher(WHEEL_COMMAND)
        cls.wheel.wait_for_subscriber(TIMEOUT)
        cls.joints = SensorSubscriber("/moving_cube/joint_states", JointState, raw)
        cls.odom = SensorSubscriber("/moving_cube/odom", Odometry, raw)
        cls.clock = SensorSubscriber("/clock", Clock, raw)
        for subscriber in (cls.joints, cls.odom, cls.clock):
            subscriber.wait_for_connection(TIMEOUT)
        cls.get_model = rospy.ServiceProxy("/gazebo/get_model_state", GetModelState)
        cls.set_model = rospy.ServiceProxy("/gazebo/set_model_state", SetModelState)
        cls.get_link = rospy.ServiceProxy("/gazebo/get_link_state", GetLinkState)
        cls.get_world = rospy.ServiceProxy("/gazebo/get_world_properties", GetWorldProperties)
        cls.get_physics = rospy.ServiceProxy("/gazebo/get_physics_properties", GetPhysicsProperties)
        cls.switch = rospy.ServiceProxy("/moving_cube/controller_manager/switch_controller", SwitchController)

    def setUp(self):
        self.gazebo.pause()
        self.controllers.reset_controllers()
        self.gazebo.reset_simulation()

    def step(self, steps):
        """Lockstep: the joint_states and odom messages of the new time."""
        joints_mark, odom_mark = self.joints.count, self.odom.count
        stamp = self.sim.step(steps, [self.wheel])
        return self.joints.wait_newer(joints_mark, TIMEOUT, stamp), self.odom.wait_newer(odom_mark, TIMEOUT, stamp)

    def model(self, **request):
        response = self.get_model(**{"model_name": "moving_cube", **request})
        self.assertTrue(response.success, response.status_message)
        return response

    # -- the tutorial's env, Gazebo style ---------------------------------------------------------
    def wait_wheel_speed(self, speed, timeout=TIMEOUT):
        """CubeSingleDiskEnv.wait_until_roll_is_in_vel, bounded: joint_states until |v - speed| <= 0.1."""
        end = time.monotonic() + timeout
        while True:
            velocity = self.joints.wait_newer(self.joints.count, TIMEOUT).velocity[0]
            if abs(velocity - speed) <= 0.1:
                return velocity
            self.assertLess(time.monotonic(), end, f"the wheel did not reach {speed} rad/s (at {velocity})")

    def test_the_tutorials_env_resets_and_steps(self):
        """RobotGazeboEnv._reset_sim(reset_controls=True), then three Gazebo-style steps of the cube env."""
        self.gazebo.unpause()
        self.controllers.reset_controllers()
        self.joints.wait_newer(self.joints.count, TIMEOUT)  # _check_all_sensors_ready
        self.odom.wait_newer(self.odom.count, TIMEOUT)
        self.wheel.publish(0.0)  # _set_init_pose: init_roll_vel
        self.wait_wheel_speed(0.0)
        self.gazebo.pause()
        self.gazebo.reset_simulation()
        self.gazebo.unpause()
        self.controllers.reset_controllers()
        self.joints.wait_newer(self.joints.count, TIMEOUT)
        self.gazebo.pause()
        stamps = []
        for speed in (100.0, 90.0, 100.0):  # actions: fixed speed, slow down, speed up
            self.gazebo.unpause()
            self.wheel.publish(speed)
            self.wait_wheel_speed(speed)
            self.gazebo.pause()
            stamps.append(self.odom.latest.header.stamp)  # _get_obs: the latest message
        self.assertEqual(stamps, sorted(stamps))
        self.assertGreater(stamps[-1], rospy.Time(0))

    # -- model and link state ---------------------------------------------------------------------
    def test_set_model_state_moves_the_cube(self):
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = 0.0, 1.0, 0.5
        pose.orientation.w = 1.0
        twist = Twist()
        twist.linear.y = 0.5
        response = self.set_model(ModelState(model_name="moving_cube", pose=pose, twist=twist, reference_frame="world"))
        self.assertTrue(response.success, response.status_message)
        state = self.model()
        self.assertEqual((state.pose.position.x, state.pose.position.y, state.pose.position.z), (0.0, 1.0, 0.5))
        self.assertAlmostEqual(state.twist.linear.y, 0.5, delta=1e-9)
        _, odom = self.step(1)
        self.assertAlmostEqual(odom.pose.pose.position.y, 1.0, delta=NOISE)
        self.assertAlmostEqual(odom.pose.pose.position.z, 0.5, delta=NOISE)
        self.step(600)  # falls 0.39 m in 0.28 s and lands (moving along y, it may tip onto an edge)
        landed = self.model().pose.position
        self.assertLess(landed.z, 0.1 * math.sqrt(2) + 0.01)
        self.assertGreater(landed.y, 1.0 + 0.5 * 0.25, "it kept the 0.5 m/s along y during the fall")

    def test_model_and_link_state_in_gazebo_names(self):
        wheel = self.get_link(link_name="moving_cube::inertia_wheel_roll", reference_frame="")
        self.assertTrue(wheel.success, wheel.status_message)
        self.assertAlmostEqual(wheel.link_state.pose.position.x, 0.1, delta=1e-6)
        self.assertEqual(wheel.link_state.link_name, "moving_cube::inertia_wheel_roll")
        relative = self.model(relative_entity_name="moving_cube::inertia_wheel_roll")
        self.assertAlmostEqual(math.hypot(relative.pose.position.x, relative.pose.position.z), 0.1, delta=1e-6)
        self.assertEqual(relative.header.frame_id, "moving_cube::inertia_wheel_roll")
        world = self.get_world()
        self.assertEqual((list(world.model_names), world.success), (["moving_cube"], True))

    def test_unknown_names_and_bad_poses_are_refused_and_change_nothing(self):
        self.assertFalse(self.get_model(model_name="no_such_model").success)
        response = self.get_model(model_name="moving_cube", relative_entity_name="no_such_frame")
        self.assertFalse(response.success)
        self.assertIn("no_such_frame", response.status_message)
        response = self.get_link(link_name="moving_cube::no_such_link", reference_frame="")
        self.assertFalse(response.success)
        self.assertIn("no_such_link", response.status_message)
        before = self.model().pose
        pose = Pose()
        pose.position.z = float("nan")
        response = self.set_model(ModelState(model_name="moving_cube", pose=pose))
        self.assertFalse(response.success)
        self.assertIn("nothing changed", response.status_message)
        self.assertFalse(self.set_model(ModelState(model_name="no_such_model", pose=Pose())).success)
        self.assertEqual(self.model().pose, before)

    # -- controllers ------------------------------------------------------------------------------
    def test_a_stopped_wheel_controller_lets_the_wheel_coast(self):
        self.wheel.publish(50.0)
        joints, _ = self.step(500)
        self.assertAlmostEqual(joints.velocity[0], 50.0, delta=1.0)
        self.assertTrue(self.switch(start_controllers=[], stop_controllers=[CONTROLLERS[1]],
                                    strictness=SwitchControllerRequest.STRICT).ok)
        self.wheel.publish(-50.0)  # a stopped controller ignores commands
        joints, _ = self.step(500)
        self.assertEqual(joints.effort[0], 0.0)
        self.assertAlmostEqual(joints.velocity[0], 50.0, delta=2.0, msg="the wheel should coast")
        self.controllers.reset_controllers()  # off (already) and on: restarted, the command is 0
        joints, _ = self.step(500)
        self.assertAlmostEqual(joints.velocity[0], 0.0, delta=1.0)

    def test_the_tutorials_own_controller_reset_restarts_running_controllers(self):
        """Their reset sends start_controllers twice, never stop: ros_control noetic restarts what runs."""
        self.wheel.publish(50.0)
        self.step(500)
        self.assertTrue(self.controllers.reset_controllers_as_the_tutorials_wrote_it())
        joints, _ = self.step(500)
        self.assertAlmostEqual(joints.velocity[0], 0.0, delta=1.0)

    # -- real-time factor -------------------------------------------------------------------------
    def sim_seconds_in(self, wall_seconds):
        """Sim time that passes while the sim runs for `wall_seconds` of wall time."""
        start = self.odom.wait_newer(self.odom.count, TIMEOUT).header.stamp  # after a reset: published
        self.gazebo.unpause()
        time.sleep(wall_seconds)  # measuring the pacing itself: wall time is the quantity under test
        self.gazebo.pause()
        self.step(1)
        return (self.odom.latest.header.stamp - start).to_sec()

    def test_max_update_rate_sets_the_real_time_factor(self):
        request = self.gazebo.request
        try:
            request.max_update_rate = 100.0  # 100 steps of 1 ms per wall second: 0.1 x real time
            self.gazebo.update_gravity_call()
            self.assertEqual(self.get_physics().max_update_rate, 100.0)
            self.gazebo.reset_simulation()
            slow = self.sim_seconds_in(1.0)
            rospy.loginfo("max_update_rate 100: %.3f s of sim time in 1 s of wall time", slow)
            self.assertLess(slow, 0.15)
            request.max_update_rate = 0.0  # as fast as possible
            self.gazebo.update_gravity_call()
            self.gazebo.reset_simulation()
            fast = self.sim_seconds_in(1.0)
            rospy.loginfo("max_update_rate 0: %.3f s of sim time in 1 s of wall time", fast)
            self.assertGreater(fast, 1.5, "as fast as possible should beat real time (cube: 50 x on an idle machine)")
        finally:
            request.max_update_rate = 1000.0
            self.gazebo.update_gravity_call()


if __name__ == "__main__":
    rostest.rosrun("workspace_tests", "gazebo_services_cube", CubeGazeboServicesTest)
