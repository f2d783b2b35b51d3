#!/usr/bin/env python3
"""Train the moving cube with Q-learning (the tutorial's start_training.py), over ROS in lockstep.

Params: /moving_cube/* (config/moving_cube_qlearn.yaml, loaded by launch/main.launch), validated
before anything is written; private params as in robot_rl.training_node. Publishes
/moving_cube/reward (each step's reward) and /moving_cube/episode_reward (each episode's return).
"""
import sys

import moving_cube_training
from moving_cube_training.params import validate_params
from moving_cube_training.state import CubeStateKey
from robot_rl.training_node import TrainingNodeSpec, run_training_node

SPEC = TrainingNodeSpec(robot="moving_cube", env_id=moving_cube_training.ENV_ID, params_namespace="/moving_cube",
                        validate_params=validate_params, make_state_key=CubeStateKey,
                        reward_topic="/moving_cube/reward", episode_reward_topic="/moving_cube/episode_reward",
                        publish_cumulated_reward=False)

if __name__ == "__main__":
    sys.exit(run_training_node(SPEC, "movingcube_gym"))
