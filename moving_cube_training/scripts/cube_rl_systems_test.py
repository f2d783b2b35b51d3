#!/usr/bin/env python3
"""The tutorial's systems test (seed 000's cube_rl_systems_test()): move the cube's wheel at 80, -80
and 0 rad/s, two seconds apart, then log the cube state, done and reward.

    roslaunch pybullet_sim cube_sim.launch paused:=false      # the sim, running
    rosrun moving_cube_training cube_rl_systems_test.py

or both at once, ending when this script is done and with its exit code:

    rosrun workspace_tools roslaunch_checked.py moving_cube_training systems_test.launch

Not in the seed: the last line is a verdict, "PASS: ..." when the wheel reached each commanded speed
(within 10 %) 2 s after the command, "FAIL: ..." otherwise or when the sim does not answer; the
exit code is 0 on PASS, 1 on FAIL.
"""
import sys
import time

import rospy

from moving_cube_training.cube_rl_utils import CubeRLUtils
from pybullet_sim.ros.client import SimConnectionError

SIM_SECONDS_BETWEEN_COMMANDS = 2.0
WALL_TIMEOUT = 30.0  # wall seconds allowed for those 2 s of sim time
SPEED_TOLERANCE = 0.1  # of the commanded speed (1 rad/s at 0): how close the wheel must get in those 2 s


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
    """Command the wheel, wait 2 s of sim time; returns how far from the command the wheel is (rad/s)."""
    cube_rl_utils_object.move_joints(roll_speed=roll_speed)
    wait_sim_time(SIM_SECONDS_BETWEEN_COMMANDS, rospy.get_rostime())
    return abs(cube_rl_utils_object.joints.velocity[0] - roll_speed)


def cube_rl_systems_test():
    """The seed's test; returns the commanded speeds the wheel did not reach (not in the seed)."""
    rospy.init_node('cube_rl_systems_test_node', anonymous=True, log_level=rospy.INFO)
    # Not in the seed: ~timeout (wall s) bounds every wait on the sim.
    cube_rl_utils_object = CubeRLUtils(timeout=float(rospy.get_param("~timeout", 10.0)))
    missed = []

    for label, roll_speed in (("80", 80.0), ("-80", -80.0), ("0.0", 0.0)):  # the seed's log lines
        rospy.loginfo("Moving to Speed==>" + label)
        error = move_and_wait(cube_rl_utils_object, roll_speed)
        if error > max(SPEED_TOLERANCE * abs(roll_speed), 1.0):
            missed.append(f"{roll_speed:g} rad/s (off by {error:.1f})")

    cube_state = cube_rl_utils_object.get_cube_state()
    done = cube_rl_utils_object.observation_checks(cube_state)
    reward = cube_rl_utils_object.get_reward_for_observations(cube_state)

    rospy.loginfo("Done==>" + str(done))
    rospy.loginfo("Reward==>" + str(reward))
    # Not in the seed: the state the reward was computed from, so the output can be checked.
    rospy.loginfo("Cube state==>" + str(cube_state))
    return missed


def main():
    try:
        missed = cube_rl_systems_test()
    except SimConnectionError as error:
        print(f"FAIL: {error}", flush=True)
        return 1
    if missed:
        print(f"FAIL: the wheel did not reach {', '.join(missed)} within {SIM_SECONDS_BETWEEN_COMMANDS:g} s",
              flush=True)
        return 1
    print("PASS: the wheel reached 80, -80 and 0 rad/s, each within 2 s of sim time", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
