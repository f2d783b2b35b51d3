"""robot_rl's public face: importing it imports neither torch, nor ray, nor rospy, and every name it lists is there."""
import subprocess
import sys

import robot_rl

HEAVY = ("torch", "stable_baselines3", "ray", "rospy")


def test_importing_the_face_imports_no_torch_ray_or_rospy():
    done = subprocess.run([sys.executable, "-c", f"import sys, robot_rl; "
                           f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))"],
                          capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "", f"import robot_rl imported {done.stdout.strip()}"


def test_every_eager_name_of_all_is_there():
    lazy = set(robot_rl._LAZY)
    assert set(robot_rl.__all__) >= lazy
    missing = [name for name in robot_rl.__all__ if name not in lazy and name not in vars(robot_rl)]
    assert missing == []


def test_an_unknown_name_is_an_attribute_error():
    assert not hasattr(robot_rl, "no_such_name")
