"""Run the same seeded Monoped-v0 episode start (crouch, tilted 0.02-0.05 rad) over ROS and on the direct
backend; print one JSON line: {"ros": [...], "direct": [...]} with the observations of reset and 25 steps."""
import json

import gymnasium
import numpy as np

import hopper_training  # noqa: F401 (registers the tasks)
from hopper_training.envs.stay_up import STAY_UP

ACTIONS = [4, 4, 6, 5, 6, 0, 3, 6] * 3 + [6]


def episode(backend: str) -> list[list[float]]:
    params = STAY_UP.default_params().with_changes("test", initial_tilt={"low": 0.02, "high": 0.05})
    env = gymnasium.make(STAY_UP.env_id, backend=backend, params=params, seed=5, ros_timeout=30.0).unwrapped
    try:
        observation, _ = env.reset(seed=5)
        observations = [observation]
        for action in ACTIONS:
            observations.append(env.step(action)[0])
        return [np.asarray(o, dtype=float).tolist() for o in observations]
    finally:
        env.close()


print(json.dumps({"ros": episode("ros"), "direct": episode("direct")}))
