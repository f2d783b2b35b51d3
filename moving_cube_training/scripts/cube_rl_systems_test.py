#!/usr/bin/env python3
"""The tutorial's systems test (seed 000's cube_rl_systems_test()): move the cube's wheel at 80, -80
and 0 rad/s, two seconds apart, then log the cube state, done and reward.

    roslaunch pybullet_sim cube_sim.launch paused:=false      # the sim, running
    rosrun moving_cube_training cube_rl_systems_test.py

or both at once: roslaunch moving_cube_training systems_test.launch (exits when this script is done).
Exit code 0 on success, 1 (with the error printed) if the sim does not answer.
"""
import sys
import time

import rospy

from moving_cube_training.cube_rl_utils import CubeRLUtils
from pybullet_sim.client import SimConnectionError

SIM_SECONDS_BETWEEN_COMMANDS = 2.0
WALL_TIMEOUT = 30.0  # wall seconds allowed for those 2 s of sim time


def wait_sim_time(duration, start, wall_timeout=WALL_TIMEOUT):
    """Wait until sim time (rospy.get_rostime(), driven by /clock) is `duration` s past `start`.

    The seed used time.sleep(2), i.e. wall time. Here it is sim time, bounded by a wall-clock
    timeout; short wall sleeps, not rospy.sleep, which would block forever while the sim is paused."""
    deadline = time.monotonic() + wall_timeout
    while True:
        now = rospy.get_rostime()
        if rospy.is_shutdown():
            raise SimConnectionError("shutdown while waiting for sim time to advance")
        # A zero start means no /clock had arrived yet when the command was sent: start at the first one.
        if start.is_zero() and not now.is_zero():
            start = now
        if not start.is_zero() and (now - start).to_sec() >= duration:
            return
        if time.monotonic() > deadline:
            advanced = 0.0 if start.is_zero() else (now - start).to_sec()
            raise SimConnectionError(
                f"/clock is not advancing: sim time advanced {advanced:.3f} s of the {duration} s awaited in "
                f"{wall_timeout} s of wall time; is the simulation paused? unpause with "
                f"rosservice call /gazebo/unpause_physics")
        time.sleep(0.005)


def move_and_wait(cube_rl_utils_object, roll_speed):
    cube_rl_utils_object.move_joints(roll_speed=roll_speed)
    wait_sim_time(SIM_SECONDS_BETWEEN_COMMANDS, rospy.get_rostime())


def cube_rl_systems_test():
    rospy.init_node('cube_rl_systems_test_node', anonymous=True, log_level=rospy.INFO)
    cube_rl_utils_object = CubeRLUtils()

    rospy.loginfo("Moving to Speed==>80")
    move_and_wait(cube_rl_utils_object, 80.0)
    rospy.loginfo("Moving to Speed==>-80")
    move_and_wait(cube_rl_utils_object, -80.0)
    rospy.loginfo("Moving to Speed==>0.0")
    move_and_wait(cube_rl_utils_object, 0.0)

    cube_state = cube_rl_utils_object.get_cube_state()
    done = cube_rl_utils_object.observation_checks(cube_state)
    reward = cube_rl_utils_object.get_reward_for_observations(cube_state)

    rospy.loginfo("Done==>" + str(done))
    rospy.loginfo("Reward==>" + str(reward))
    # Not in the seed: the state the reward was computed from, so the output can be checked.
    rospy.loginfo("Cube state==>" + str(cube_state))


def main():
    try:
        cube_rl_systems_test()
    except SimConnectionError as error:
        rospy.logerr(f"cube_rl_systems_test failed: {error}")  # on stderr, and in the node's log
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
