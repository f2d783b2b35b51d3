"""A deep agent's trained run as a deterministic policy: the agent registry's policy loader, for evaluate.py and
the training video."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import DummyVecEnv

from ...params import ParamError
from ...runs.loaded import LoadedRun
from ...runs.results import RunFileError
from ...workers.base import as_env_actions
from .params import NetworkParams
from .trainer import CHECKPOINT_FORMAT, build_model, one_line_reason


class DeepPolicy:
    """A trained run's deterministic policy: observation -> action."""

    def __init__(self, model: BaseAlgorithm):
        self.model = model

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        action, _ = self.model.predict(observation, deterministic=True)
        return as_env_actions(action, self.model.action_space, 1)[0]


def greedy_policy(run: LoadedRun, checkpoint: dict[str, Any]) -> Callable[[gymnasium.Env[Any, Any], int], DeepPolicy]:
    """The greedy policy of a deep run: the model rebuilt from agent.json's params, its weights from model.zip."""
    try:
        if checkpoint.get("format") != CHECKPOINT_FORMAT:
            raise ValueError(f"format {checkpoint.get('format')!r}")
        agent_params = run.agent.load_params_from(checkpoint["agent_params"], str(run.path))
    except (KeyError, TypeError, ValueError, ParamError) as error:
        raise ValueError(f"{run.path}: not a deep agent's checkpoint ({error})") from None
    assert isinstance(agent_params, NetworkParams)

    def policy(env: gymnasium.Env[Any, Any], _seed: int) -> DeepPolicy:
        torch.set_num_threads(1)
        model = build_model(agent_params, DummyVecEnv([lambda: env]), run.params.gamma, run.params.seed)
        model_zip = run.path.with_name("model.zip")
        try:
            model.set_parameters(str(model_zip), exact_match=True, device="cpu")
        except Exception as error:  # noqa: BLE001 (zipfile, torch and SB3 each raise their own)
            raise RunFileError(f"{model_zip}: not weights of this run's model: {one_line_reason(error)}") from None
        return DeepPolicy(model)
    return policy
