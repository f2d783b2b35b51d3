"""Python package setup for robot_rl; run by catkin_python_setup(), not by hand."""
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["robot_rl"], package_dir={"": "src"}))
