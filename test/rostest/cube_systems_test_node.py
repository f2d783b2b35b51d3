#!/usr/bin/env python3
"""rostest node: the tutorial's systems test script against the running sim, and CubeRLUtils directly."""
import math
import os
import re
import signal
import subprocess
import time
import unittest
from unittest import mock

import rospy
import rostest
from geometry_msgs.msg import Point
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Empty

from moving_cube_training import cube_rl_utils
from moving_cube_training.cube_rl_utils import CubeRLUtils
from pybullet_sim.ros.client import SimConnectionError

SCRIPT = ["rosrun", "moving_cube_training", "cube_rl_systems_test.py"]
SCRIPT_TIMEOUT = 120.0  # wall s; the script needs ~6 s of sim time (~6 s at real time) plus start-up
TIMEOUT = 10.0
FLOAT = r"[-+]?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|inf|nan)"


def run_script(*args):
    """Run the script (inherited environment: this rostest's master, use_sim_time), output captured."""
    process = subprocess.Popen([*SCRIPT, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    try:
        stdout, stderr = process.communicate(timeout=SCRIPT_TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)  # the process group started just above
        stdout, stderr = process.communicate()
        raise AssertionError(f"{' '.join(SCRIPT)} did not finish within {SCRIPT_TIMEOUT} s\n{stdout}\n{stderr}") \
            from None
    return process.returncode, stdout + stderr, stdout.strip().splitlines()[-1] if stdout.strip() else ""


def hand_made_state(distance):
    return [0.0, distance, 0.0, 0.0, 0.0]


class CubeSystemsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("cube_systems_test")
        for name in ("/gazebo/pause_physics", "/gazebo/unpause_physics"):
            rospy.wait_for_service(name, TIMEOUT)
        cls.pause = rospy.ServiceProxy("/gazebo/pause_physics", Empty)
        cls.unpause = rospy.ServiceProxy("/gazebo/unpause_physics", Empty)

    def test_systems_test_script(self):
        returncode, output, verdict = run_script()
        self.assertEqual(returncode, 0, output)
        lines = output.splitlines()
        for text in ("Moving to Speed==>80", "Moving to Speed==>-80", "Moving to Speed==>0.0"):
            self.assertTrue(any(line.endswith(text) for line in lines), f"no '{text}' line in\n{output}")
        order = [output.index(text) for text in ("Moving to Speed==>80\n", "Moving to Speed==>-80\n",
                                                 "Moving to Speed==>0.0\n", "Done==>", "Reward==>")]
        self.assertEqual(order, sorted(order), "the script's lines are out of order")

        done = re.search(r"Done==>(True|False)$", output, re.M)
        reward = re.search(rf"Reward==>({FLOAT})$", output, re.M)
        state = re.search(rf"Cube state==>\[({FLOAT}(?:, {FLOAT}){{4}})\]$", output, re.M)
        self.assertIsNotNone(done, output)
        self.assertIsNotNone(reward, output)
        self.assertIsNotNone(state, output)
        speed, distance, roll, pitch, yaw = (float(v) for v in state.group(1).split(", "))
        self.assertTrue(all(math.isfinite(v) for v in (speed, distance, roll, pitch, yaw)), state.group(0))
        self.assertAlmostEqual(float(reward.group(1)), 10.0 * distance - abs(speed), places=9)
        self.assertEqual(done.group(1), str(distance > 2.0))
        # The wheel was last commanded to 0 rad/s, 2 s of sim time before the state was taken.
        self.assertLess(abs(speed), 5.0, state.group(0))
        self.assertEqual(verdict, "PASS: the wheel reached 80, -80 and 0 rad/s, each within 2 s of sim time")

    def test_utils_against_the_running_sim(self):
        utils = CubeRLUtils(timeout=TIMEOUT)
        # The odom wait is not skipped (the seed's bug) and both first messages are kept.
        self.assertIsNotNone(utils.cube_odom_data)
        self.assertIsNotNone(utils.disk_joints_data)
        state = utils.get_cube_state()
        self.assertEqual(len(state), 5)
        self.assertTrue(all(type(v) is float and math.isfinite(v) for v in state), state)
        self.assertEqual(state, [round(v, 1) for v in state])

    def test_get_distance_from_point(self):
        utils = CubeRLUtils.__new__(CubeRLUtils)  # the pure helpers need no connection
        self.assertAlmostEqual(utils.get_distance_from_point(Point(0, 0, 0), Point(3, 4, 0)), 5.0)
        self.assertAlmostEqual(utils.get_distance_from_point(Point(1, 1, 1), Point(1, 1, 1)), 0.0)
        self.assertAlmostEqual(utils.get_distance_from_point(Point(1, -2, 2), Point(0, 0, 0)), 3.0)

    def test_observation_checks_and_reward(self):
        utils = CubeRLUtils.__new__(CubeRLUtils)
        self.assertFalse(utils.observation_checks(hand_made_state(0.0)))
        self.assertFalse(utils.observation_checks(hand_made_state(2.0)))  # strictly farther than 2 m
        self.assertTrue(utils.observation_checks(hand_made_state(2.1)))
        self.assertAlmostEqual(utils.get_reward_for_observations([-3.0, 1.5, 0.1, 0.2, 0.3]), 12.0)
        self.assertAlmostEqual(utils.get_reward_for_observations([80.0, 0.5, 0.0, 0.0, 0.0]), -75.0)

    def test_missing_topics_fail_with_bounded_waits(self):
        """Each wait gives up after the timeout, naming the topic (odom too: the seed never waited for it)."""
        for constant, topic in (("JOINT_STATES_TOPIC", "/no_sim/joint_states"), ("ODOM_TOPIC", "/no_sim/odom"),
                                ("ROLL_COMMAND_TOPIC", "/no_sim/command")):
            with self.subTest(topic=topic), mock.patch.object(cube_rl_utils, constant, topic):
                start = time.monotonic()
                with self.assertRaises(SimConnectionError) as raised:
                    CubeRLUtils(timeout=1.0)
                self.assertLess(time.monotonic() - start, 5.0)
                self.assertIn(topic, str(raised.exception))
                self.assertIn("roslaunch pybullet_sim cube_sim.launch paused:=false", str(raised.exception))

    def test_systems_test_script_fails_with_a_verdict_on_a_paused_sim(self):
        self.pause()
        try:
            returncode, output, verdict = run_script("_timeout:=1.0")
        finally:
            self.unpause()
        self.assertEqual(returncode, 1, output)
        self.assertTrue(verdict.startswith("FAIL: no message on /moving_cube/joint_states"), output)

    def test_paused_sim_times_out(self):
        """A paused sim publishes nothing, so the sensor check gives up after its timeout."""
        self.pause()
        try:
            start = time.monotonic()
            with self.assertRaises(SimConnectionError) as raised:
                CubeRLUtils(timeout=1.0)
            self.assertLess(time.monotonic() - start, 5.0)
            self.assertIn("/moving_cube/joint_states", str(raised.exception))
            self.assertIn("unpaused", str(raised.exception))
        finally:
            self.unpause()
        paused_at = rospy.get_rostime()
        rospy.wait_for_message("/clock", Clock, TIMEOUT)  # running again before the next test
        deadline = time.monotonic() + TIMEOUT
        while rospy.get_rostime() <= paused_at and time.monotonic() < deadline:
            time.sleep(0.01)
        self.assertGreater(rospy.get_rostime(), paused_at, "/clock did not advance after unpause")


if __name__ == "__main__":
    rostest.rosrun("workspace_tests", "cube_systems_test", CubeSystemsTest)
