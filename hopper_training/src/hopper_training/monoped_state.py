"""MonopedState: the tutorial's observation, reward and done logic of the monoped, on Readings.

The tutorial's class subscribed to /odom, /monoped/imu/data, /lowerleg_contactsensor_state and
/monoped/joint_states itself; here a backend hands it the same readings (update()), so the same
code runs over ROS and in-process. Fixes: the contact force drops to 0 when the foot leaves the
ground (the tutorial kept the last value), and orientation comes from tf's euler_from_quaternion
as before, without `import tf` side effects.
"""
from __future__ import annotations

import math
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
from tf.transformations import euler_from_quaternion

from robot_rl.backends import Readings
from robot_rl.discretiser import Discretiser

JOINTS = ("haa_joint", "hfe_joint", "kfe_joint")
JOINT_LIMITS = {"haa_joint": (-1.6, 1.6), "hfe_joint": (-1.6, 1.6), "kfe_joint": (-1.6, 0.0)}  # the URDF's
ODOMETRY_SENSOR = "p3d_base_controller"
IMU_SENSOR = "gazebo_ros_imu_controller"
CONTACT_SENSOR = "lowerleg_contactsensor_sensor"
OBSERVATIONS = ("distance_from_desired_point", "base_roll", "base_pitch", "base_yaw", "contact_force",
                "joint_states_haa", "joint_states_hfe", "joint_states_kfe")


class MonopedState:
    def __init__(self, max_height: float, min_height: float, abs_max_roll: float, abs_max_pitch: float,
                 joint_increment_value: float = 0.05, done_reward: float = -1000.0, alive_reward: float = 10.0,
                 desired_force: float = 7.08, desired_yaw: float = 0.0, weight_r1: float = 1.0,
                 weight_r2: float = 1.0, weight_r3: float = 1.0, weight_r4: float = 1.0, weight_r5: float = 1.0,
                 discrete_division: int = 10):
        self.max_height, self.min_height = max_height, min_height
        self.abs_max_roll, self.abs_max_pitch = abs_max_roll, abs_max_pitch
        self.joint_increment_value = joint_increment_value
        self.done_reward, self.alive_reward = done_reward, alive_reward
        self.desired_force, self.desired_yaw = desired_force, desired_yaw
        self.weights = (weight_r1, weight_r2, weight_r3, weight_r4, weight_r5)
        self.desired_world_point = (0.0, 0.0, 0.0)
        self.readings: Optional[Readings] = None
        self._base_rpy = (0.0, 0.0, 0.0)
        # The tutorial's bins: numpy.linspace(min, max, discrete_division) per observation.
        self.discretiser = Discretiser(
            low=[-(max_height - min_height), -abs_max_roll, -abs_max_pitch, -2 * math.pi, 0.0, -1.6, -1.6, -1.6],
            high=[max_height - min_height, abs_max_roll, abs_max_pitch, 2 * math.pi, 2 * desired_force, 1.6, 1.6, 0.0],
            bins=discrete_division)

    @classmethod
    def from_params(cls, params: Dict) -> "MonopedState":
        state = cls(params["max_height"], params["min_height"], params["max_incl"], params["max_incl"],
                    params["joint_increment_value"], params["done_reward"], params["alive_reward"],
                    params["desired_force"], params["desired_yaw"],
                    *(params[f"weight_r{i}"] for i in range(1, 6)))
        state.set_desired_world_point(params["desired_pose/x"], params["desired_pose/y"], params["desired_pose/z"])
        return state

    def update(self, readings: Readings) -> None:
        self.readings = readings
        self._base_rpy = euler_from_quaternion(readings.sensors[IMU_SENSOR].orientation)

    def set_desired_world_point(self, x: float, y: float, z: float) -> None:
        self.desired_world_point = (x, y, z)

    # -- readings -----------------------------------------------------------------------------
    def get_base_position(self) -> Tuple[float, float, float]:
        return self.readings.sensors[ODOMETRY_SENSOR].position

    def get_base_height(self) -> float:
        return self.get_base_position()[2]

    def get_base_rpy(self) -> Tuple[float, float, float]:
        return self._base_rpy

    def get_distance_from_point(self, point: Sequence[float]) -> float:
        return math.dist(self.get_base_position(), point)

    def get_contact_force_magnitude(self) -> float:
        """|total_wrench.force| of the foot's contact; 0 in the air."""
        contact = self.readings.sensors[CONTACT_SENSOR]
        return math.hypot(*contact.total_force) if contact.contacts else 0.0

    def get_joint_positions(self) -> List[float]:
        joints = self.readings.joints
        return [joints.position[joints.name.index(name)] for name in JOINTS]

    # -- done and reward ----------------------------------------------------------------------
    def monoped_height_ok(self) -> bool:
        return self.min_height <= self.get_base_height() < self.max_height

    def monoped_orientation_ok(self) -> bool:
        roll, pitch, _ = self.get_base_rpy()
        return abs(roll) < self.abs_max_roll and abs(pitch) < self.abs_max_pitch

    def calculate_reward_joint_position(self) -> float:
        return self.weights[0] * sum(abs(p) for p in self.readings.joints.position)

    def calculate_reward_joint_effort(self) -> float:
        return self.weights[1] * sum(abs(e) for e in self.readings.joints.effort)

    def calculate_reward_contact_force(self) -> float:
        return self.weights[2] * abs(self.get_contact_force_magnitude() - self.desired_force)

    def calculate_reward_orientation(self) -> float:
        roll, pitch, yaw = self.get_base_rpy()
        return self.weights[3] * (abs(roll) + abs(pitch) + abs(yaw - self.desired_yaw))

    def calculate_reward_distance_from_des_point(self) -> float:
        return self.weights[4] * self.get_distance_from_point(self.desired_world_point)

    def calculate_total_reward(self) -> float:
        return self.alive_reward - (self.calculate_reward_joint_position() + self.calculate_reward_joint_effort()
                                    + self.calculate_reward_contact_force() + self.calculate_reward_orientation()
                                    + self.calculate_reward_distance_from_des_point())

    def process_data(self) -> Tuple[float, bool]:
        """(reward, done): done_reward when the base left [min_height, max_height) or tilted too far."""
        done = not (self.monoped_height_ok() and self.monoped_orientation_ok())
        return (self.done_reward, True) if done else (self.calculate_total_reward(), False)

    # -- observations, states and actions -----------------------------------------------------
    def get_observations(self) -> np.ndarray:
        """The 8 observations in the tutorial's order (OBSERVATIONS)."""
        roll, pitch, yaw = self.get_base_rpy()
        return np.array([self.get_distance_from_point(self.desired_world_point), roll, pitch, yaw,
                         self.get_contact_force_magnitude(), *self.get_joint_positions()], dtype=np.float32)

    def get_state_as_string(self, observation: np.ndarray) -> str:
        """The tutorial's 10-bin digitising of the 8 observations, as a Q-table key."""
        return self.discretiser.key(observation)

    def get_action_to_position(self, action: int, joint_positions: Sequence[float]) -> List[float]:
        """Targets for haa, hfe, kfe: the current positions with one joint moved by +/-increment
        (actions 0..5: haa+, haa-, hfe+, hfe-, kfe+, kfe-), clamped to the URDF limits."""
        targets = list(joint_positions)
        joint, direction = divmod(action, 2)
        targets[joint] += self.joint_increment_value * (1 if direction == 0 else -1)
        low, high = JOINT_LIMITS[JOINTS[joint]]
        targets[joint] = min(max(targets[joint], low), high)
        return targets
