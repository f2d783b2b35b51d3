#!/usr/bin/env python3
"""rostest node: MovingCubeOneDiskWalk-v0 on the ROS backend passes gymnasium's env checker, and a
seeded episode repeats exactly over ROS and matches the direct backend (same sim seed 0).

Both tests share one ROS env: a second RosBackend in the same node loses the lockstep guarantee
(see test_cube_training.py::test_a_second_backend_in_one_node_applies_every_command, which also
runs this file as a plain script with --second-backend-cycles N).
"""
import json
import sys
import unittest
import warnings

import gymnasium
import numpy as np
import rospy
from gymnasium.utils.env_checker import check_env

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from moving_cube_training.robot import MOVING_CUBE

SIM_SEED = 0  # cube_sim.launch's default seed
ACTIONS = [int(a) for a in np.random.default_rng(7).integers(0, 5, size=30)]
WHEEL = "inertia_wheel_roll_joint_velocity_controller"


def episode(env):
    """Seeded reset, then the same 30 actions: every observation, reward, flags and sim time."""
    observation, info = env.reset(seed=SIM_SEED)
    trace = [(observation, 0.0, False, False, info["sim_time"])]
    for action in ACTIONS:
        observation, reward, terminated, truncated, info = env.step(action)
        trace.append((observation, reward, terminated, truncated, info["sim_time"]))
    return trace


class CubeEnvTest(unittest.TestCase):
    maxDiff = None

    @classmethod
    def setUpClass(cls):
        rospy.init_node("cube_env_test")
        cls.env = gymnasium.make(ONE_DISK_WALK.env_id, backend="ros")

    @classmethod
    def tearDownClass(cls):
        cls.env.close()

    def test_env_checker_passes_over_ros(self):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(self.env.unwrapped)
        # y distance and y speed are unbounded on purpose; rospy itself leaves sockets to the
        # garbage collector and calls the deprecated notifyAll.
        problems = [str(w.message) for w in caught
                    if not issubclass(w.category, (ResourceWarning, DeprecationWarning))
                    and "infinity" not in str(w.message)]
        self.assertEqual(problems, [])

    def test_seeded_episodes_repeat_over_ros_and_match_direct(self):
        first, second = episode(self.env), episode(self.env)
        direct_env = gymnasium.make(ONE_DISK_WALK.env_id, backend="direct", seed=SIM_SEED)
        try:
            direct = episode(direct_env)
        finally:
            direct_env.close()
        self.assertEqual(len(first), len(ACTIONS) + 1)
        observations = np.array([t[0] for t in first])
        self.assertGreater(np.abs(observations - observations[0]).max(), 1e-3,
                           "the actions should change the observation")
        for name, other, tolerance in (("second ROS run", second, 0.0), ("direct backend", direct, 1e-9)):
            for k, (a, b) in enumerate(zip(first, other)):
                np.testing.assert_allclose(b[0], a[0], rtol=0, atol=tolerance,
                                           err_msg=f"{name}: observation {k} differs")
                self.assertAlmostEqual(b[1], a[1], delta=1e-6, msg=f"{name}: reward {k}")
                self.assertEqual(b[2:4], a[2:4], f"{name}: terminated/truncated {k}")
                self.assertAlmostEqual(b[4], a[4], delta=1e-9, msg=f"{name}: sim time {k}")


def lockstep_misses(backend, cycles):
    """Publish-then-step `cycles` times (one physics step each): how many steps did not use the
    command published just before them. With p = 1 the wheel's effort is clamp(command - velocity)."""
    misses = 0
    velocity = backend.reset(restart_time=True).joints.velocity[0]
    for k in range(cycles):
        command = (60.0 if k % 2 == 0 else -60.0) + (k % 7)
        backend.set_command(WHEEL, command)
        joints = backend.step(1).joints
        misses += joints.effort[0] != max(-200.0, min(200.0, command - velocity))
        velocity = joints.velocity[0]
    return misses


def second_backend(cycles):
    """Two RosBackends one after the other in one node; prints the misses of each as JSON."""
    from robot_rl import RosBackend
    rospy.init_node("cube_env_second_backend")
    misses = []
    for _ in range(2):
        backend = RosBackend(MOVING_CUBE, timeout=10.0)
        try:
            misses.append(lockstep_misses(backend, cycles))
        finally:
            backend.close()
    print(json.dumps({"first": misses[0], "second": misses[1]}), flush=True)


if __name__ == "__main__":
    if "--second-backend-cycles" in sys.argv:
        second_backend(int(sys.argv[sys.argv.index("--second-backend-cycles") + 1]))
    else:
        import rostest
        rostest.rosrun("workspace_tests", "cube_env", CubeEnvTest)
