"""The Q-table's greedy policy of a trained run: the agent registry's policy loader for tabular Q-learning."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np

from ...runs.loaded import LoadedRun
from .qlearn import QLearn


def greedy_policy(run: LoadedRun, checkpoint: dict[str, Any]) -> Callable[[gymnasium.Env[Any, Any], int],
                                                                           Callable[[np.ndarray], int]]:
    """The Q-table's greedy policy (ties broken by an RNG seeded with the seed given), checked against
    the state key the run's params make."""
    try:
        qlearn, saved_key = QLearn.from_dict(checkpoint["qlearn"]), checkpoint["state_key"]
    except (KeyError, TypeError) as error:
        raise ValueError(f"{run.path}: not a training checkpoint (missing {error})") from None
    state_key = run.task.state_key(run.params)
    if state_key.to_dict() != saved_key:
        raise ValueError(f"{run.path}: the Q-table was trained with another state key than this code makes from "
                         f"{run.params_file}")

    def policy(_env: gymnasium.Env[Any, Any], seed: int) -> Callable[[np.ndarray], int]:
        qlearn.rng.seed(seed)
        return lambda observation: qlearn.greedy_action(state_key.key(observation))
    return policy
