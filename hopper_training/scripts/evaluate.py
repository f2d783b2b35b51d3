#!/usr/bin/env python3
"""Evaluate a trained monoped run (greedy vs random policy): robot_rl.evaluation for the monoped's tasks.

  rosrun hopper_training evaluate.py --qtable training_results/monoped/latest [--episodes 20] [--horizon-s 10]
  rosrun hopper_training evaluate.py --policy controller [--task hop] [--speed 0.4]   # the hopping controller

A run's metrics: mean_return, mean_time_upright_s, upright_whole_horizon_rate and mean_x_distance
(m along +x). See robot_rl/src/robot_rl/evaluation.py for every option.
"""
import sys

from hopper_training import TASKS
from hopper_training.controller_policy import ControllerPolicy, controller_params
from robot_rl.evaluation import ScriptedPolicy, main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], TASKS, "evaluate_monoped",
                  {"controller": ScriptedPolicy(controller_params, ControllerPolicy)}))
