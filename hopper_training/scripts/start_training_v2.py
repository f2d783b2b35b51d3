#!/usr/bin/env python3
"""Train the monoped with Q-learning: seed 001's start_training_v2.py in Python 3, over ROS in lockstep.

Params at the root namespace (config/hopper_qlearn.yaml, loaded by launch/hopper.launch), validated
before anything is written; private params as in robot_rl.training_node (~nepisodes overrides the
YAML's 100000). Publishes /monoped/reward (the cumulated reward after every step, as the tutorial)
and /monoped/episode_reward (each episode's return); logs "EP: ..." per episode, the final table,
"Overall score" and "Best 100 score" (without the tutorial's missing `reduce` import and its
division by zero when no episode ended by a fall).
"""
import sys

import hopper_training
from hopper_training.monoped_state import MonopedState
from hopper_training.params import validate_params
from robot_rl.training_node import TrainingNodeSpec, run_training_node


class MonopedStateKey:
    """The tutorial's state string: MonopedState's 10-bin digitising of the 8 observations."""

    def __init__(self, params):
        self.monoped_state = MonopedState.from_params(params)

    def key(self, observation):
        return self.monoped_state.get_state_as_string(observation)

    def to_dict(self):
        return self.monoped_state.discretiser.to_dict()


SPEC = TrainingNodeSpec(robot="monoped", env_id=hopper_training.ENV_ID, params_namespace="/",
                        validate_params=validate_params, make_state_key=MonopedStateKey,
                        reward_topic="/monoped/reward", episode_reward_topic="/monoped/episode_reward",
                        publish_cumulated_reward=True)

if __name__ == "__main__":
    sys.exit(run_training_node(SPEC, "monoped_gym"))
