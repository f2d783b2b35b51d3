from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["pybullet_sim", "pybullet_sim.ros"], package_dir={"": "src"}))
