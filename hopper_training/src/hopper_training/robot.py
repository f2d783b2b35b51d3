"""The monoped robot: its RobotSpec, joint, controller and sensor names, and what the tasks read from its Readings."""
from __future__ import annotations

import math

from tf.transformations import euler_from_quaternion

from robot_rl import Readings, RobotSpec

CONTROLLERS = ("haa_joint_position_controller", "hfe_joint_position_controller", "kfe_joint_position_controller")
JOINTS = ("haa_joint", "hfe_joint", "kfe_joint")
ODOMETRY_SENSOR = "p3d_base_controller"
IMU_SENSOR = "gazebo_ros_imu_controller"
CONTACT_SENSOR = "lowerleg_contactsensor_sensor"

MONOPED = RobotSpec(description_package="hopper_description", urdf="urdf/monoped.urdf",
                    sim_config="config/hopper_sim.yaml", sim_launch="roslaunch pybullet_sim hopper_sim.launch")


def joint_positions(readings: Readings) -> list[float]:
    """haa, hfe, kfe positions, read by name."""
    joints = readings.joints
    return [joints.position[joints.name.index(name)] for name in JOINTS]


def joint_velocities(readings: Readings) -> list[float]:
    """haa, hfe, kfe velocities, read by name."""
    joints = readings.joints
    return [joints.velocity[joints.name.index(name)] for name in JOINTS]


def base_rpy(readings: Readings) -> tuple[float, float, float]:
    """The base's roll, pitch and yaw from the IMU (tf's euler_from_quaternion, axes sxyz)."""
    roll, pitch, yaw = euler_from_quaternion(readings.imu(IMU_SENSOR).orientation)
    return roll, pitch, yaw


def contact_force(readings: Readings) -> float:
    """abs(total_wrench.force) of the foot's contact; 0 in the air."""
    contact = readings.contact(CONTACT_SENSOR)
    return math.hypot(*contact.total_force) if contact.contacts else 0.0
