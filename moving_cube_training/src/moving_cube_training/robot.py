"""The moving cube robot: its RobotSpec and its wheel's controller, joint and odometry sensor names."""
from __future__ import annotations

from robot_rl import RobotSpec

WHEEL_CONTROLLER = "inertia_wheel_roll_joint_velocity_controller"
ODOMETRY_SENSOR = "p3d_base_controller"
WHEEL_JOINT = "inertia_wheel_roll_joint"

MOVING_CUBE = RobotSpec(description_package="moving_cube_description", urdf="urdf/moving_cube.urdf",
                        sim_config="config/moving_cube_sim.yaml", sim_launch="roslaunch pybullet_sim cube_sim.launch")
