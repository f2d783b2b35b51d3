"""Helper of test_faults_restarted_sim.py: the cube's env over ROS, stepped once, then (once a line arrives on
stdin: the sim has been killed, and started again or not) stepped three times and reset once; prints each error as
one line "TYPE: MESSAGE"."""
import sys

import gymnasium

import moving_cube_training  # noqa: F401  (registers the env)

env = gymnasium.make("MovingCubeOneDiskWalk-v0", backend="ros", ros_timeout=10.0)
env.reset(seed=0)
env.step(0)
print("ready", flush=True)
sys.stdin.readline()
for call in (lambda: env.step(0), lambda: env.step(1), lambda: env.step(2), lambda: env.reset()):
    try:
        call()
        print("no error", flush=True)
    except Exception as error:  # noqa: BLE001  (what a user's script meets: any type)
        print(f"{type(error).__name__}: {' '.join(str(error).split())}", flush=True)
