#!/usr/bin/env python3
"""Evaluate a trained cube run (greedy vs random policy): robot_rl.evaluation for the cube's tasks.

  rosrun moving_cube_training evaluate.py --qtable training_results/moving_cube/latest [--episodes 20]

A run's metrics: mean_return, mean_y_distance (m along +y) and success_rate (episodes that ended
at least 0.5 m along +y). See robot_rl/src/robot_rl/evaluation.py for every option.
"""
import sys

from moving_cube_training import TASKS
from robot_rl import evaluation_main as main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], TASKS, "evaluate_moving_cube"))
