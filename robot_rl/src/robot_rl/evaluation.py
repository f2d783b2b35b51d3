"""What both robots' evaluate.py share: loading a trained run, and the greedy-vs-random comparison."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable, Dict, Tuple

import numpy as np
import yaml

from .qlearn import QLearn

EpisodeRunner = Callable[[Any, Callable[[np.ndarray], int], int], Dict[str, float]]


def load_trained_run(qtable: Path, validate_params: Callable[[Dict, str], Dict]) -> Tuple[QLearn, Dict[str, Any]]:
    """The Q-learner and validated params of a run, from its qtable.json or its folder."""
    path = qtable / "qtable.json" if qtable.is_dir() else qtable
    qlearn = QLearn.from_dict(json.loads(path.read_text())["qlearn"])
    params_file = path.with_name("params.yaml")
    return qlearn, validate_params(yaml.safe_load(params_file.read_text()), str(params_file))


def greedy_and_random(env, state_key: Callable[[np.ndarray], str], qlearn: QLearn, episodes: int, seed: int,
                      run_episodes: EpisodeRunner) -> Tuple[Dict[str, float], Dict[str, float]]:
    """Run the greedy policy, then a seeded random one, for `episodes` each; closes the env."""
    qlearn.rng.seed(seed)
    rng = np.random.default_rng(seed)
    try:
        env.reset(seed=seed)
        greedy = run_episodes(env, lambda obs: qlearn.greedy_action(state_key(obs)), episodes)
        random_policy = run_episodes(env, lambda obs: int(rng.integers(env.action_space.n)), episodes)
    finally:
        env.close()
    return greedy, random_policy
