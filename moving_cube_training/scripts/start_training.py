#!/usr/bin/env python3
"""Train the moving cube with Q-learning (the tutorial's start_training.py), over ROS in lockstep.

Params: /moving_cube/* (config/one_disk_walk.yaml, loaded by launch/main.launch), validated before
anything is written; private params as in robot_rl.training_node. Publishes /moving_cube/reward
(each step's reward) and /moving_cube/episode_reward (each episode's return).
"""
import sys

from moving_cube_training import TASKS
from robot_rl import run_training_node

if __name__ == "__main__":
    sys.exit(run_training_node(TASKS, "movingcube_gym"))
