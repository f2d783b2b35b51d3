#!/usr/bin/env python3
"""Each contact sensor's force as an rviz arrow (see pybullet_sim.contact_markers)."""
import sys

from pybullet_sim.contact_markers import main

if __name__ == "__main__":
    sys.exit(main())
