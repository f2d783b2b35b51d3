#!/usr/bin/env python3
"""Evaluate a trained monoped run (greedy vs random policy): robot_rl.evaluation for the monoped's tasks.

  rosrun hopper_training evaluate.py --qtable training_results/monoped/latest [--episodes 20] [--horizon-s 10]
  rosrun hopper_training evaluate.py --policy controller [--task hop] [--speed 0.4]   # the hopping controller
  rosrun hopper_training evaluate.py --policy do_nothing --task hop_in_place          # the hop-level baselines:
  rosrun hopper_training evaluate.py --policy random --task hop_in_place              # (controller too)

A run's metrics: mean_return, mean_time_upright_s, upright_whole_horizon_rate and mean_x_distance
(m along +x). See robot_rl/src/robot_rl/evaluation.py for every option.
Hand-written policies (--policy): controller, the hopping controller (hopper_training.controller_policy;
on --task hop_in_place its neutral point and speed feedback switched on under the do-nothing action);
do_nothing, hop_in_place's do-nothing action every hop; random, a uniformly random action every step
(numpy's default_rng(0)), for a baseline before any run is trained.
"""
import sys

import numpy as np

from hopper_training import TASKS, controller_policy, hop_level
from robot_rl.evaluation import ScriptedPolicy, main, random_actions


def controller_params(task, params):
    if task is hop_level.HOP_LEVEL:
        return hop_level.controller_params(params)
    return controller_policy.controller_params(task, params)


def controller(env, speed):
    if env.unwrapped.task is hop_level.HOP_LEVEL:
        return hop_level.do_nothing_policy(env, speed)
    return controller_policy.ControllerPolicy(env, speed)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:], TASKS, "evaluate_monoped", {
        "controller": ScriptedPolicy(controller_params, controller),
        "do_nothing": ScriptedPolicy(lambda task, params: params, hop_level.do_nothing_policy),
        "random": ScriptedPolicy(lambda task, params: params,
                                 lambda env, speed: random_actions(env.action_space, np.random.default_rng(0)))}))
