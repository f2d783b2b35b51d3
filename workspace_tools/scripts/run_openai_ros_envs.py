#!/usr/bin/env python3
"""Run openai_ros's own task env for the cube or the hopper on the PyBullet sim (workspace_tools.openai_ros_envs)."""
import sys

from workspace_tools.openai_ros_envs import main

if __name__ == "__main__":
    sys.exit(main())
