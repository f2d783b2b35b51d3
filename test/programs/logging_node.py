"""A node that stops on SIGINT/SIGTERM as the training node does (pybullet_sim.ros.shutdown.shutdown_on_signals)
while it logs as fast as it can, so that the signal lands inside a log line (each holds rospy's
master proxy lock). Creates the file named by its argument once it logs, exits 130 once stopped."""
import sys
from pathlib import Path

import rospy

from pybullet_sim.ros.shutdown import shutdown_on_signals
from robot_rl import INTERRUPTED

rospy.init_node("logging_node", anonymous=True, disable_signals=True)
signals = shutdown_on_signals()
rospy.loginfo("line 0")
Path(sys.argv[1]).touch()
line = 1
while not signals:
    rospy.loginfo("line %d", line)
    line += 1
sys.exit(INTERRUPTED)
