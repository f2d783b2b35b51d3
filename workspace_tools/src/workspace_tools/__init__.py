"""workspace_tools: what the tests, the benchmark and ./ws need around the workspace (private masters,
process clean-up, roslaunch with exit codes, the checkout's paths, Gazebo-style service clients); not part
of the RL library."""
