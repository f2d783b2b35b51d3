"""Helper of test_vector_ros.py: a vector env of two ROS workers that steps until it is interrupted.

Prints one JSON line once it steps: the pids of the workers and of every master and sim node they
started. It does nothing on Ctrl-C itself, as a user's script would not: the test checks that SIGINT
to the process group leaves no process behind. Its one argument is the workers' log folder (the test's: a worker
whose sim the Ctrl-C ended keeps its logs there, not in /tmp)."""
import json
import sys

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import make_vector_env


def main() -> None:
    env = make_vector_env(ONE_DISK_WALK, 2, backend="ros", seed=0, log_dir=sys.argv[1])
    env.reset(seed=0)
    pids = [pid for info in env.workers.worker_info for pid in (info["pid"], *info["children"])]
    print(json.dumps(pids), flush=True)
    while True:
        env.step([0, 1])


if __name__ == "__main__":
    main()
