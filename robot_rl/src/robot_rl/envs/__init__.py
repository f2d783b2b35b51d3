"""The task envs' base and the backends that reach the robot (over ROS or in-process)."""
