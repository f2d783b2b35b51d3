#!/usr/bin/env python3
"""rostest node: the hopper tutorial's GazeboConnection and ControllersConnection against the sim.

The tutorial's MonopedEnv resets with gravity switched off (pause, reset_simulation, gravity 0,
controllers off/on, init pose, check the sensors, gravity back on, pause). Here our own clients make the
same calls (workspace_tools.gazebo_style), and the physics is checked: without gravity the hopper does not fall,
gravity survives both resets, the controller switch restarts the controllers and gates joint_states."""
import math
import time
import unittest

import rospy
import rostest
from geometry_msgs.msg import Vector3
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState

from controller_manager_msgs.srv import (
    ListControllers,
    LoadController,
    SwitchController,
    SwitchControllerRequest,
    UnloadController,
)
from gazebo_msgs.msg import ContactsState, ODEPhysics
from gazebo_msgs.srv import GetModelState, GetPhysicsProperties, SetPhysicsProperties, SetPhysicsPropertiesRequest
from pybullet_sim.ros.client import CommandPublisher, SensorSubscriber, SimConnection
from workspace_tools.gazebo_style import TUTORIAL_ODE, ControllersConnection, GazeboConnection

TIMEOUT = 10.0
NAMESPACE = "monoped"
JOINTS = ("haa_joint", "hfe_joint", "kfe_joint")
CONTROLLERS = ["joint_state_controller"] + [f"{joint}_position_controller" for joint in JOINTS]
SPAWN_Z = 1.0  # the foot hangs 5 cm above the ground
STANDING_Z = 0.95
STRICT, BEST_EFFORT = SwitchControllerRequest.STRICT, SwitchControllerRequest.BEST_EFFORT


def raw(msg):
    return msg


class HopperGazeboServicesTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("gazebo_services_hopper_test")
        cls.gazebo = GazeboConnection(gravity=(0.0, 0.0, 0.0))  # MonopedEnv's: gravity off from the start
        cls.controllers = ControllersConnection(NAMESPACE, CONTROLLERS)
        cls.sim = SimConnection(timeout=TIMEOUT)
        cls.commands = [CommandPublisher(f"/monoped/{joint}_position_controller/command") for joint in JOINTS]
        for publisher in cls.commands:
            publisher.wait_for_subscriber(TIMEOUT)
        cls.joints = SensorSubscriber("/monoped/joint_states", JointState, raw)
        cls.odom = SensorSubscriber("/odom", Odometry, raw)
        cls.sensors = (cls.joints, cls.odom, SensorSubscriber("/monoped/imu/data", Imu, raw),
                       SensorSubscriber("/lowerleg_contactsensor_state", ContactsState, raw))
        for subscriber in cls.sensors:
            subscriber.wait_for_connection(TIMEOUT)
        cls.model_state = rospy.ServiceProxy("/gazebo/get_model_state", GetModelState)
        cls.get_physics = rospy.ServiceProxy("/gazebo/get_physics_properties", GetPhysicsProperties)
        cls.set_physics = rospy.ServiceProxy("/gazebo/set_physics_properties", SetPhysicsProperties)
        manager = f"/{NAMESPACE}/controller_manager"
        cls.switch = rospy.ServiceProxy(f"{manager}/switch_controller", SwitchController)
        cls.list = rospy.ServiceProxy(f"{manager}/list_controllers", ListControllers)
        cls.load = rospy.ServiceProxy(f"{manager}/load_controller", LoadController)
        cls.unload = rospy.ServiceProxy(f"{manager}/unload_controller", UnloadController)

    def setUp(self):
        """Every test starts paused, gravity on, controllers running, at the spawn pose."""
        self.gazebo.change_gravity(0.0, 0.0, -9.81)
        self.gazebo.pause()
        self.controllers.reset_controllers()
        self.gazebo.reset_simulation()

    def base_z(self):
        response = self.model_state(model_name="monoped")
        self.assertTrue(response.success, response.status_message)
        return response.pose.position.z

    def step(self, steps):
        """Lockstep: advance `steps` physics steps; the odom message of the new time."""
        mark = self.odom.count
        stamp = self.sim.step(steps, self.commands)
        return self.odom.wait_newer(mark, TIMEOUT, stamp)

    def wait_sim_time(self, seconds):
        """While running: wait until /odom (every 1 ms of sim time) is stamped `seconds` later (each wait bounded)."""
        start = self.odom.wait_newer(self.odom.count, TIMEOUT).header.stamp
        while (self.odom.wait_newer(self.odom.count, TIMEOUT).header.stamp - start).to_sec() < seconds:
            pass

    # -- the tutorial's reset ---------------------------------------------------------------------
    def test_the_tutorials_reset_sequence_keeps_the_hopper_up_while_gravity_is_off(self):
        """MonopedEnv._reset, call for call; the sim runs (unpaused) between gravity off and gravity on."""
        self.gazebo.pause()
        self.gazebo.reset_simulation()
        self.gazebo.change_gravity(0.0, 0.0, 0.0)  # pause, set, unpause: the sim now runs without gravity
        self.controllers.reset_controllers()
        for publisher in self.commands:  # set_init_pose
            publisher.publish(0.0)
        for subscriber in self.sensors:  # check_all_systems_ready
            subscriber.wait_newer(subscriber.count, TIMEOUT)
        self.wait_sim_time(0.3)  # three free falls of 5 cm would have landed
        self.assertAlmostEqual(self.base_z(), SPAWN_Z, delta=1e-4, msg="the hopper fell without gravity")
        self.gazebo.change_gravity(0.0, 0.0, -9.81)
        self.gazebo.pause()
        self.step(300)
        self.assertAlmostEqual(self.base_z(), STANDING_Z, delta=0.02, msg="with gravity back it should stand")

    def test_gravity_survives_reset_world_and_reset_simulation(self):
        self.gazebo.change_gravity(0.0, 0.0, 0.0)
        self.gazebo.pause()
        for reset in (self.gazebo.reset_world, self.gazebo.reset_simulation):
            reset()
            self.step(500)
            self.assertAlmostEqual(self.base_z(), SPAWN_Z, delta=1e-4, msg=f"fell after {reset.resolved_name}")
        physics = self.get_physics()
        self.assertEqual((physics.gravity.x, physics.gravity.y, physics.gravity.z), (0.0, 0.0, 0.0))
        self.assertTrue(physics.pause)

    def test_bad_physics_requests_change_nothing(self):
        before = self.get_physics()
        good = dict(time_step=0.001, max_update_rate=1000.0, gravity=Vector3(0.0, 0.0, -9.81))
        for name, changes in (("nan gravity", dict(gravity=Vector3(0.0, 0.0, math.nan))),
                              ("infinite time step", dict(time_step=math.inf)),
                              ("zero time step", dict(time_step=0.0)),
                              ("negative update rate", dict(max_update_rate=-1.0)),
                              ("no solver iterations",
                               dict(ode_config=ODEPhysics(**TUTORIAL_ODE | {"sor_pgs_iters": 0}))),
                              ("erp above 1", dict(ode_config=ODEPhysics(**TUTORIAL_ODE | {"erp": 2.0})))):
            request = SetPhysicsPropertiesRequest(**{**good, "ode_config": ODEPhysics(**TUTORIAL_ODE), **changes})
            response = self.set_physics(request)
            self.assertFalse(response.success, name)
            self.assertIn("nothing changed", response.status_message, name)
            self.assertEqual(self.get_physics(), before, f"{name} changed the physics")
        self.step(300)
        self.assertLess(self.base_z(), SPAWN_Z - 0.03, "gravity should still pull")

    def test_a_new_time_step_changes_the_physics_step(self):
        request = SetPhysicsPropertiesRequest(time_step=0.002, max_update_rate=500.0, gravity=Vector3(0.0, 0.0, -9.81),
                                              ode_config=ODEPhysics(**TUTORIAL_ODE))
        try:
            self.assertTrue(self.set_physics(request).success)
            physics = self.get_physics()
            self.assertEqual((physics.time_step, physics.max_update_rate), (0.002, 500.0))
            first = self.step(1).header.stamp
            self.assertEqual(self.step(10).header.stamp - first, rospy.Duration(0, 20_000_000))
        finally:
            request.time_step, request.max_update_rate = 0.001, 1000.0
            self.assertTrue(self.set_physics(request).success)

    # -- ros_control ------------------------------------------------------------------------------
    def states(self):
        return {c.name: c.state for c in self.list().controller}

    def test_list_controllers_reports_ros_controls_fields(self):
        controllers = {c.name: c for c in self.list().controller}
        self.assertEqual(set(controllers), set(CONTROLLERS))
        hfe = controllers["hfe_joint_position_controller"]
        self.assertEqual((hfe.state, hfe.type), ("running", "effort_controllers/JointPositionController"))
        self.assertEqual([(r.hardware_interface, r.resources) for r in hfe.claimed_resources],
                         [("hardware_interface::EffortJointInterface", ["hfe_joint"])])
        self.assertEqual(controllers["joint_state_controller"].type, "joint_state_controller/JointStateController")

    def test_a_stopped_joint_state_controller_stops_joint_states(self):
        stopped_at = self.step(1).header.stamp
        self.assertTrue(self.switch(start_controllers=[], stop_controllers=["joint_state_controller"],
                                    strictness=STRICT).ok)
        mark = self.joints.count
        self.step(20)  # odom of the new time has arrived; joint_states of a time after the stop must not come
        deadline = time.monotonic() + 0.3
        with self.assertRaisesRegex(Exception, "no new message"):
            while True:  # one published before the stop may still be on its way (a loaded machine): not counted
                late = self.joints.wait_newer(mark, max(deadline - time.monotonic(), 0.0))
                self.assertLessEqual(late.header.stamp, stopped_at, "joint_states of a time after the stop")
                mark = self.joints.count
        self.assertTrue(self.switch(start_controllers=["joint_state_controller"], stop_controllers=[],
                                    strictness=STRICT).ok)
        stamp = self.step(1).header.stamp
        self.assertEqual(self.joints.wait_newer(mark, TIMEOUT, stamp).header.stamp, stamp)

    def test_the_controller_reset_restarts_a_position_controller_where_the_joint_is(self):
        self.step(200)  # stand on the foot
        self.commands[1].publish(0.6)
        angle = self.hfe_after(40)  # hfe is on its way to 0.6
        self.assertGreater(angle, 0.01)
        self.assertLess(angle, 0.45)
        self.controllers.reset_controllers()  # restarted, hfe holds the angle it has now
        self.assertAlmostEqual(self.hfe_after(300), angle, delta=0.05, msg="hfe went on towards 0.6")

    def hfe_after(self, steps):
        """hfe's angle in the joint_states message of the step's new time (not an older one still in flight)."""
        mark = self.joints.count
        stamp = self.step(steps).header.stamp
        return self.joints.wait_newer(mark, TIMEOUT, stamp).position[1]

    def test_strict_switch_with_an_unknown_name_changes_nothing(self):
        ok = self.switch(start_controllers=[], stop_controllers=["hfe_joint_position_controller", "no_such"],
                         strictness=STRICT).ok
        self.assertFalse(ok)
        self.assertEqual(set(self.states().values()), {"running"})
        ok = self.switch(start_controllers=[], stop_controllers=["hfe_joint_position_controller", "no_such"],
                         strictness=BEST_EFFORT).ok
        self.assertTrue(ok)
        self.assertEqual(self.states()["hfe_joint_position_controller"], "stopped")

    def test_switching_works_while_paused_and_load_unload(self):
        self.assertTrue(self.get_physics().pause)
        name = "kfe_joint_position_controller"
        self.assertFalse(self.unload(name=name).ok, "a running controller must not unload")
        self.assertTrue(self.switch(start_controllers=[], stop_controllers=[name], strictness=STRICT).ok)
        self.assertTrue(self.unload(name=name).ok)
        self.assertNotIn(name, self.states())
        self.assertFalse(self.load(name="no_such_controller").ok)
        self.assertTrue(self.load(name=name).ok)
        self.assertEqual(self.states()[name], "initialized")
        self.assertTrue(self.switch(start_controllers=[name], stop_controllers=[], strictness=STRICT).ok)
        self.assertEqual(self.states()[name], "running")


if __name__ == "__main__":
    rostest.rosrun("workspace_tests", "gazebo_services_hopper", HopperGazeboServicesTest)
