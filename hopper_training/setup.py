"""Python package setup for hopper_training; run by catkin_python_setup(), not by hand."""
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["hopper_training", "hopper_training.controller", "hopper_training.envs"],
                                 package_dir={"": "src"}))
