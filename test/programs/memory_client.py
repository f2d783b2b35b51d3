"""Run by test_faults.py: 10,000 resets and 100,000 one-physics-step lockstep steps of the cube over ROS,
after a warm-up; prints the growth of the sim node's (pid as argument) and this client's resident memory."""
import json
import sys
from pathlib import Path

from moving_cube_training.robot import MOVING_CUBE, WHEEL_CONTROLLER
from robot_rl import RosBackend


def resident_kib(pid: int | str) -> int:
    status = Path(f"/proc/{pid}/status").read_text()
    return int(next(line.split()[1] for line in status.splitlines() if line.startswith("VmRSS:")))


def exercise(backend: RosBackend, resets: int, steps: int) -> None:
    for _ in range(resets):
        backend.reset()
    for k in range(steps):
        backend.set_command(WHEEL_CONTROLLER, 50.0 if k % 2 else -50.0)
        backend.step(1)


def main(sim_pid: int) -> None:
    backend = RosBackend(MOVING_CUBE, timeout=10.0)
    try:
        exercise(backend, 1000, 10000)  # warm-up: caches, allocator pools
        before = resident_kib(sim_pid), resident_kib("self")
        exercise(backend, 10000, 100000)
        after = resident_kib(sim_pid), resident_kib("self")
    finally:
        backend.close()
    print(json.dumps({"resets": 10000, "steps": 100000, "sim_kib": after[0] - before[0],
                      "client_kib": after[1] - before[1]}))


if __name__ == "__main__":
    main(int(sys.argv[1]))
