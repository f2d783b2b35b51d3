#!/usr/bin/env python3
"""Evaluate a trained monoped run (greedy vs random policy): robot_rl.evaluation for the monoped's tasks.

  rosrun hopper_training evaluate.py --qtable training_results/stay_up/latest [--episodes 20] [--horizon-s 10]
  rosrun hopper_training evaluate.py --policy controller [--task hop] [--speed 0.4]   # the hopping controller
  rosrun hopper_training evaluate.py --policy do_nothing --task hop_in_place          # the hop-level baselines:
  rosrun hopper_training evaluate.py --policy random --task hop_in_place              # (controller too)
  rosrun hopper_training evaluate.py --policy do_nothing --task residual_forward      # no residual
  rosrun hopper_training evaluate.py --policy constant --action 2 --task hop_in_place # one action every hop
  rosrun hopper_training evaluate.py --policy placement_by_speed --task hop_in_place  # +2, +4, +6 cm by speed

A run's metrics: mean_return, mean_time_upright_s, upright_whole_horizon_rate and mean_x_distance
(m along +x). See robot_rl/src/robot_rl/evaluation.py for every option.
Hand-written policies (--policy): controller, the hopping controller (hopper_training.controller.policy;
on --task hop_in_place and the residual tasks its neutral point and speed feedback switched on under the
do-nothing action); do_nothing, hop_in_place's do-nothing action every hop, or no residual on the residual
tasks (residual_in_place, residual_forward: commanded their target_speed); placement_by_speed, on hop_in_place
the foot 2 cm + 2 cm per m/s of speed ahead, rounded to an offset level (hopper_training.scripted_policies);
random, a uniformly random action every step (numpy's default_rng(0)), for a baseline before any run is trained.
"""
import sys

from hopper_training import TASKS
from hopper_training.scripted_policies import POLICIES
from robot_rl import evaluation_main as main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], TASKS, "evaluate_monoped", POLICIES))
