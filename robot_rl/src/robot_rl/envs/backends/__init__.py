"""How a task env reaches its robot: the Backend protocol, the in-process and ROS backends, one factory."""
