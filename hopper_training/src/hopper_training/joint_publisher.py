"""JointPub: the tutorial's three joint position commands, sent through a backend (ROS topics
/monoped/{haa,hfe,kfe}_joint_position_controller/command, or an in-process World)."""
from __future__ import annotations

from typing import Sequence

from robot_rl.backends import Backend

CONTROLLERS = ("haa_joint_position_controller", "hfe_joint_position_controller", "kfe_joint_position_controller")


class JointPub:
    def __init__(self, backend: Backend):
        self.backend = backend

    def set_init_pose(self) -> None:
        self.move_joints([0.0, 0.0, 0.0])

    def move_joints(self, joints_array: Sequence[float]) -> None:
        for controller, position in zip(CONTROLLERS, joints_array):
            self.backend.set_command(controller, float(position))
