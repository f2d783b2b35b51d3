#!/usr/bin/env python3
"""The PyBullet stand-in for Gazebo (see pybullet_sim.ros.node)."""
import signal
import sys

if __name__ == "__main__":
    # Until the node sets its own handler, SIGINT ends it at once and quietly, as it does any ROS node: roslaunch
    # stops every node when a required one fails fast, often while this one is still importing (Python's own
    # handler would print a KeyboardInterrupt traceback from the middle of an import).
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    import rospy

    from pybullet_sim.ros.node import main
    sys.exit(main(rospy.myargv(sys.argv)))
