"""Python package setup for workspace_tools; run by catkin_python_setup(), not by hand."""
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["workspace_tools", "workspace_tools.bench"], package_dir={"": "src"}))
