"""Agent rllib_ppo's saved weights and its greedy policy, in numpy: no Ray, no torch, no pickle.

A run's weights are its RLModule's state (RLlib's DefaultPPOTorchRLModule: the actor's and the critic's MLP
encoders, tanh, and their linear heads) as numpy arrays by their state-dict names in `rllib_module.npz`, read
with allow_pickle=False; agent.json records the file's sha256 (`weights_sha256`) and nothing loads a file
that differs. RLlib's own checkpoints (pickled) are never written nor read. The greedy policy is the actor's
forward pass: for Discrete actions the most likely one, for a Box the Gaussian's mean, clipped to [-1, 1] and
scaled onto the space's bounds as RLlib's normalize_actions does (evaluate.py --run, ./ws demo, ship_policy.py).
"""
from __future__ import annotations

import hashlib
import io
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from ...atomic import write_bytes_atomic
from ...runs.loaded import LoadedRun
from ...runs.results import RunFileError

CHECKPOINT_FORMAT = "robot_rl.rllib_ppo/1"  # agent.json of an rllib_ppo run
WEIGHTS_FILE = "rllib_module.npz"
PARTIAL_WEIGHTS = "rllib_module.partial.npz"  # being written: renamed once agent.json names its sha256
WEIGHTS_DIGEST = "weights_sha256"
ACTOR, HEAD = "encoder.actor_encoder.net.mlp", "pi.net.mlp"


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def save_weights(path: Path, arrays: dict[str, np.ndarray]) -> str:
    """Write `arrays` to `path` whole (atomically); returns the file's sha256."""
    data = npz_bytes({name: np.asarray(value) for name, value in arrays.items()})
    write_bytes_atomic(path, data)
    return hashlib.sha256(data).hexdigest()


def sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def load_weights(path: Path, digest: Any, checkpoint: Path) -> dict[str, np.ndarray]:
    """The arrays of `path` if it is the file `checkpoint` recorded (sha256 `digest`); else RunFileError naming it."""
    if not isinstance(digest, str):
        raise RunFileError(f"{path}: {checkpoint} records no {WEIGHTS_DIGEST} of it, so nothing tells it is this "
                           f"run's weights")
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise RunFileError(f"{path}: missing: the checkpoint {checkpoint} needs it") from None
    if hashlib.sha256(data).hexdigest() != digest:
        raise RunFileError(f"{path}: not the weights {checkpoint} recorded (its sha256 differs): damaged, cut short, "
                           f"or another run's")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as arrays:
            return {name: arrays[name] for name in arrays.files}
    except (OSError, ValueError) as error:
        raise RunFileError(f"{path}: not numpy weights ({error})") from None


def _layers(weights: dict[str, np.ndarray], prefix: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """The linear layers named `prefix`.<i>.weight / .bias, in order of i."""
    indices = sorted({int(m[1]) for name in weights if (m := re.fullmatch(rf"{re.escape(prefix)}\.(\d+)\.weight",
                                                                           name))})
    return [(weights[f"{prefix}.{i}.weight"].astype(np.float64), weights[f"{prefix}.{i}.bias"].astype(np.float64))
            for i in indices]


class NumpyPpoPolicy:
    """observation -> greedy action of an rllib_ppo actor (see the module docstring)."""

    def __init__(self, weights: dict[str, np.ndarray], action_space: gymnasium.spaces.Space[Any], source: str):
        self.encoder, self.head = _layers(weights, ACTOR), _layers(weights, HEAD)
        self.action_space = action_space
        if not self.encoder or len(self.head) != 1:
            raise RunFileError(f"{source}: no actor of RLlib's PPO module in it (layers {ACTOR}.* and {HEAD}.0)")
        outputs = self.head[0][0].shape[0]
        if isinstance(action_space, gymnasium.spaces.Discrete):
            expected = int(action_space.n)
        elif isinstance(action_space, gymnasium.spaces.Box):
            expected = 2 * int(np.prod(action_space.shape))  # mean and log std
        else:
            raise ValueError(f"{source}: rllib_ppo acts in Discrete or Box spaces, not {action_space}")
        if outputs != expected:
            raise ValueError(f"{source}: the policy has {outputs} outputs, {action_space} needs {expected}")

    @property
    def inputs(self) -> int:
        return int(self.encoder[0][0].shape[1])

    def __call__(self, observation: np.ndarray) -> int | np.ndarray:
        h = np.asarray(observation, np.float64).reshape(-1)
        for weights, bias in self.encoder:
            h = np.tanh(weights @ h + bias)
        weights, bias = self.head[0]
        out = weights @ h + bias
        space = self.action_space
        if isinstance(space, gymnasium.spaces.Discrete):
            return int(space.start) + int(np.argmax(out))
        assert isinstance(space, gymnasium.spaces.Box)
        mean: np.ndarray = np.clip(out[:out.shape[0] // 2], -1.0, 1.0)
        low, high = np.asarray(space.low, np.float64), np.asarray(space.high, np.float64)
        action = low + (mean + 1.0) * (high - low) / 2.0
        return action.reshape(space.shape).astype(space.dtype)


def greedy_policy(run: LoadedRun, checkpoint: dict[str, Any]) -> Callable[[gymnasium.Env[Any, Any], int], Any]:
    """Agent rllib_ppo's loader (robot_rl.agents.registry): the weights beside the checkpoint, checked by sha256."""
    if checkpoint.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{run.path}: not an rllib_ppo checkpoint (format {checkpoint.get('format')!r})")
    path = run.path.with_name(WEIGHTS_FILE)
    weights = load_weights(path, checkpoint.get(WEIGHTS_DIGEST), run.path)

    def policy(env: gymnasium.Env[Any, Any], _seed: int) -> NumpyPpoPolicy:
        played = NumpyPpoPolicy(weights, env.action_space, str(path))
        size = int(np.prod(env.observation_space.shape or (1,)))
        if played.inputs != size:
            raise ValueError(f"{path}: the policy takes {played.inputs} inputs, the env observes {size}")
        return played
    return policy
