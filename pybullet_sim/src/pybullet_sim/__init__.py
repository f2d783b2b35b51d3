"""PyBullet stand-in for Gazebo: World (physics, no ROS), the sim node, and the SimConnection client."""
