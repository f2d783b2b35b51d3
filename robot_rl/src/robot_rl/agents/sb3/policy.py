"""A deep agent's trained run as a deterministic policy: the agent registry's policy loader, for evaluate.py and
the training video.

No policy plays unless its model.zip is the file its agent.json recorded: the sha256 there (`model_sha256`) must
match before any env is made, and the weights must then fit the model rebuilt from agent.json's params; else one
RunFileError naming model.zip (a checkpoint without a digest is refused too: nothing tells its model.zip is its own).
The recorded bytes are read once: a run whose trainer writes a checkpoint meanwhile (agent.json, then its
model.partial.zip renamed model.zip) plays the model its agent.json named, from the partial file if not yet renamed.
"""
from __future__ import annotations

import hashlib
from collections.abc import Callable
from io import BytesIO
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.vec_env import DummyVecEnv

from ...params import ParamError
from ...runs.loaded import LoadedRun
from ...runs.results import RunFileError
from ...workers.base import as_env_actions
from .params import NetworkParams
from .trainer import CHECKPOINT_FORMAT, PARTIAL_MODEL, build_model, one_line_reason

MODEL_DIGEST = "model_sha256"  # agent.json's key: the sha256 of its model.zip (as the trainer writes it)


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
    model_zip = run.path.with_name("model.zip")
    weights = read_model_zip(model_zip, checkpoint.get(MODEL_DIGEST), run.path)

    def policy(env: gymnasium.Env[Any, Any], _seed: int) -> DeepPolicy:
        torch.set_num_threads(1)
        model = build_model(agent_params, DummyVecEnv([lambda: env]), run.params.gamma, run.params.seed)
        try:
            _, tensors, _ = load_from_zip_file(BytesIO(weights), device="cpu", load_data=False)
            model.set_parameters(tensors, exact_match=True, device="cpu")
        except Exception as error:  # noqa: BLE001 (zipfile, torch and SB3 each raise their own)
            raise RunFileError(f"{model_zip}: not weights of this run's model: {one_line_reason(error)}") from None
        return DeepPolicy(model)
    return policy


def read_model_zip(model_zip: Path, digest: Any, checkpoint: Path) -> bytes:
    """The bytes of the model `checkpoint` recorded (its sha256 `digest`): model.zip's, or model.partial.zip's while
    a trainer has written that checkpoint and not yet renamed the file; else RunFileError naming `model_zip`."""
    if not isinstance(digest, str):
        raise RunFileError(f"{model_zip}: {checkpoint} records no {MODEL_DIGEST} of it, so nothing tells it is this "
                           f"run's model: a run written before digests is refused (resume:=true writes a checkpoint "
                           f"with one)")
    found = False
    for path in (model_zip, model_zip.with_name(PARTIAL_MODEL)):
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            continue
        found = True
        if hashlib.sha256(data).hexdigest() == digest:
            return data
    if not found:
        raise RunFileError(f"{model_zip}: missing: the checkpoint {checkpoint} needs it")
    raise RunFileError(f"{model_zip}: not the model.zip {checkpoint} recorded (its sha256 differs): damaged, cut "
                       f"short, or another run's")
