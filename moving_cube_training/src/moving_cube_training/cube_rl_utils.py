"""The tutorial's reinforcement-learning test harness for the moving cube (seed 000's cube_rl_utils.py).

CubeRLUtils connects to the cube's topics (joint states, odometry, wheel velocity command), moves the
wheel, and computes the state, the done flag and the reward exactly as the tutorial does. It is the
seed's class ported to Python 3; the differences are marked with comments:

* every wait is bounded (``timeout`` seconds of wall time) and fails with a
  :class:`pybullet_sim.ros.client.SimConnectionError` that names the topic and what to check;
* the seed's odometry wait tested the joint-states variable, so odom was never waited for (fixed);
* the messages received while checking the sensors are the initial ``joints`` / ``odom``, so
  :meth:`CubeRLUtils.get_cube_state` works before the first subscriber callback.

The systems test that drives it is ``scripts/cube_rl_systems_test.py``.
"""
import time

import numpy
import rospy
from geometry_msgs.msg import Point
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from tf.transformations import euler_from_quaternion

from pybullet_sim.ros.client import SimConnectionError

JOINT_STATES_TOPIC = "/moving_cube/joint_states"
ODOM_TOPIC = "/moving_cube/odom"
ROLL_COMMAND_TOPIC = "/moving_cube/inertia_wheel_roll_joint_velocity_controller/command"
SIM_HINT = "is the sim running and unpaused? roslaunch pybullet_sim cube_sim.launch paused:=false"


class CubeRLUtils:
    def __init__(self, timeout=10.0):
        # Not in the seed: the seed waited forever; every wait here gives up after `timeout` wall seconds.
        self.timeout = timeout
        self.check_all_sensors_ready()
        rospy.Subscriber(JOINT_STATES_TOPIC, JointState, self.joints_callback)
        rospy.Subscriber(ODOM_TOPIC, Odometry, self.odom_callback)
        self._roll_vel_pub = rospy.Publisher(ROLL_COMMAND_TOPIC, Float64, queue_size=1)
        self.check_publishers_connection()

    def _wait_for_first_message(self, topic, msg_type, not_ready_log, deadline):
        """The seed's retry loop (wait_for_message with a 1 s timeout, log, retry), bounded by `deadline`.

        The seed retried forever; here the retries stop at the deadline (monotonic wall clock) with a
        SimConnectionError naming the topic."""
        while True:
            if rospy.is_shutdown():
                raise SimConnectionError(f"shutdown while waiting for a message on {topic}")
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise SimConnectionError(f"no message on {topic} within {self.timeout} s; {SIM_HINT} "
                                         f"(check `rostopic hz {topic}`)")
            try:
                # rospy.wait_for_message's timeout is wall time, so a paused sim cannot stall it.
                return rospy.wait_for_message(topic, msg_type, timeout=min(1.0, remaining))
            except rospy.ROSException:  # the seed used a bare except; timeouts and shutdown raise this
                if rospy.is_shutdown():
                    raise SimConnectionError(f"shutdown while waiting for a message on {topic}") from None
                rospy.logerr(not_ready_log)

    def check_all_sensors_ready(self):
        # One deadline (self.timeout wall seconds) for both topics.
        deadline = time.monotonic() + self.timeout
        self.disk_joints_data = None
        self.disk_joints_data = self._wait_for_first_message(
            JOINT_STATES_TOPIC, JointState,
            "Current moving_cube/joint_states not ready yet, retrying for getting joint_states", deadline)
        rospy.loginfo("Current moving_cube/joint_states READY=>" + str(self.disk_joints_data))

        # Bug fix: the seed's loop here was `while self.disk_joints_data is None`, which is already
        # set at this point, so odom was never waited for and cube_odom_data stayed None.
        self.cube_odom_data = None
        self.cube_odom_data = self._wait_for_first_message(
            ODOM_TOPIC, Odometry, "Current /moving_cube/odom not ready yet, retrying for getting odom", deadline)
        rospy.loginfo("Current /moving_cube/odom READY=>" + str(self.cube_odom_data))

        # Not in the seed: start from these messages so get_cube_state works before the first
        # callback (the seed raised AttributeError if called that early).
        self.joints = self.disk_joints_data
        self.odom = self.cube_odom_data
        rospy.loginfo("ALL SENSORS READY")

    def check_publishers_connection(self):
        """
        Checks that all the publishers are working
        :return:
        """
        # The seed polled with rospy.Rate(10), which sleeps in sim time: under use_sim_time a paused
        # sim would stall it forever. Here: a 10 Hz wall-clock poll, bounded by self.timeout.
        deadline = time.monotonic() + self.timeout
        while self._roll_vel_pub.get_num_connections() == 0:
            if rospy.is_shutdown():
                raise SimConnectionError(f"shutdown while waiting for a subscriber on {ROLL_COMMAND_TOPIC}")
            if time.monotonic() > deadline:
                raise SimConnectionError(f"nobody subscribed to {ROLL_COMMAND_TOPIC} within {self.timeout} s; "
                                         f"{SIM_HINT}")
            rospy.loginfo("No susbribers to _roll_vel_pub yet so we wait and try again")
            time.sleep(0.1)
        rospy.loginfo("_base_pub Publisher Connected")
        rospy.loginfo("All Publishers READY")

    def joints_callback(self, data):
        self.joints = data

    def odom_callback(self, data):
        self.odom = data

    # Reinforcement Learning Utility Code
    def move_joints(self, roll_speed):
        joint_speed_value = Float64()
        joint_speed_value.data = roll_speed
        rospy.loginfo("Single Disk Roll Velocity>>" + str(joint_speed_value))
        self._roll_vel_pub.publish(joint_speed_value)

    def get_cube_state(self):
        # We convert from quaternions to euler
        orientation_list = [self.odom.pose.pose.orientation.x,
                            self.odom.pose.pose.orientation.y,
                            self.odom.pose.pose.orientation.z,
                            self.odom.pose.pose.orientation.w]
        roll, pitch, yaw = euler_from_quaternion(orientation_list)

        # We get the distance from the origin
        start_position = Point()
        start_position.x = 0.0
        start_position.y = 0.0
        start_position.z = 0.0
        distance = self.get_distance_from_point(start_position, self.odom.pose.pose.position)

        # Python 3: float() keeps the seed's plain floats (Python 2's round() returned a float; Python 3's
        # round() of a numpy.float64 stays numpy.float64, which numpy 2 prints as np.float64(...)).
        cube_state = [
            float(round(self.joints.velocity[0], 1)),
            float(round(distance, 1)),
            float(round(roll, 1)),
            float(round(pitch, 1)),
            float(round(yaw, 1)),
        ]
        return cube_state

    def observation_checks(self, cube_state):
        # MAximum distance to travel permited in meters from origin
        max_distance = 2.0
        if cube_state[1] > max_distance:
            rospy.logerr("Cube Too Far==>" + str(cube_state[1]))
            done = True
        else:
            rospy.loginfo("Cube NOT Too Far==>" + str(cube_state[1]))
            done = False
        return done

    def get_distance_from_point(self, pstart, p_end):
        """
        Given a Vector3 Object, get distance from current position
        :param p_end:
        :return:
        """
        a = numpy.array((pstart.x, pstart.y, pstart.z))
        b = numpy.array((p_end.x, p_end.y, p_end.z))
        distance = numpy.linalg.norm(a - b)
        return distance

    def get_reward_for_observations(self, state):
        # We reward it for lower speeds and distance traveled
        speed = state[0]
        distance = state[1]

        # Positive Reinforcement
        reward_distance = distance * 10.0
        # Negative Reinforcement for magnitude of speed
        reward_for_efective_movement = -1 * abs(speed)

        reward = reward_distance + reward_for_efective_movement

        rospy.loginfo("Reward_distance=" + str(reward_distance))
        rospy.loginfo("Reward_for_efective_movement= " + str(reward_for_efective_movement))

        return reward
