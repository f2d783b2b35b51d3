#!/usr/bin/env python3
"""Each contact sensor's force as an rviz arrow (see pybullet_sim.ros.markers)."""
import signal
import sys

if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # quietly while it imports, as sim_node.py
    from pybullet_sim.ros.markers import main
    sys.exit(main())
