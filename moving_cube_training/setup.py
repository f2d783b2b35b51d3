"""Python package setup for moving_cube_training; run by catkin_python_setup(), not by hand."""
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["moving_cube_training", "moving_cube_training.envs"],
                                 package_dir={"": "src"}))
