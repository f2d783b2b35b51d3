#!/usr/bin/env python3
"""The monoped's hopping controller as a ROS node (see hopper_training.hop_controller_node)."""
import sys

from hopper_training.hop_controller_node import main

if __name__ == "__main__":
    sys.exit(main())
