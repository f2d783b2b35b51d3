#!/usr/bin/env python3
"""The PyBullet stand-in for Gazebo (see pybullet_sim.node)."""
import sys

import rospy

from pybullet_sim.node import main

if __name__ == "__main__":
    sys.exit(main(rospy.myargv(sys.argv)))
