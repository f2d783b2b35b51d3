"""robot_rl: tabular Q-learning for ROS robots (Q-table, discretiser, parameters, results on disk)."""
