"""The sim's ROS side: the sim node, Gazebo's services, readings <-> messages, the client, the contact markers."""
