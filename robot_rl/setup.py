"""Python package setup for robot_rl; run by catkin_python_setup(), not by hand."""
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(
    packages=["robot_rl", "robot_rl.agents", "robot_rl.agents.qlearn", "robot_rl.agents.sb3", "robot_rl.envs",
              "robot_rl.envs.backends", "robot_rl.runs", "robot_rl.workers"],
    package_dir={"": "src"}))
