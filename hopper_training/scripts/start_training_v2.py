#!/usr/bin/env python3
"""Train the monoped with Q-learning: seed 001's start_training_v2.py in Python 3, over ROS in lockstep.

Params at the root namespace (config/<task>.yaml, loaded by launch/main.launch), validated before
anything is written; private params as in robot_rl.training_node (~task: stay_up or hop).
Publishes /monoped/reward (the cumulated reward after every step, as the tutorial) and
/monoped/episode_reward (each episode's return); logs "EP: ..." per episode, the final table,
"Overall score" and "Best 100 score" (without the tutorial's missing `reduce` import and its
division by zero when no episode ended by a fall).
"""
import sys

from hopper_training import TASKS
from robot_rl import run_training_node

if __name__ == "__main__":
    sys.exit(run_training_node(TASKS, "monoped_gym"))
