#!/usr/bin/env python3
"""A live plot of a training run's reward topics (see robot_rl.reward_plot)."""
import sys

import rospy

from robot_rl.reward_plot import main

if __name__ == "__main__":
    sys.exit(main(rospy.myargv(sys.argv)[1:]))
