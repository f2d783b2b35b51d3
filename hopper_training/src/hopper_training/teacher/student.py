"""The student: an MLP (tanh) from MonopedEndToEnd-v0's observation (its frames and last action) to the three
joint targets, every control period; its files hold weights and numbers only (no pickle, no torch.save):

  student.npz   the layers' weights and biases (numpy arrays W0, b0, W1, b1, ...), read with allow_pickle=False
  student.json  the architecture (sizes, activation) and the observation normaliser (mean, std per input)

`StudentNet` trains (torch); `NumpyStudent` plays (numpy: a batch of one is faster without torch), and is what
evaluate.py --run RUN loads (greedy_policy, the agent registry's loader of agent bc_dagger).
"""
from __future__ import annotations

import hashlib
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from robot_rl import LoadedRun, RunFileError, write_bytes_atomic, write_json_atomic

WEIGHTS_FILE = "student.npz"
ARCHITECTURE_FILE = "student.json"
ARCHITECTURE_FORMAT = "hopper_training.student/1"
CHECKPOINT_FORMAT = "hopper_training.bc_dagger/1"  # agent.json of a bc_dagger run
# agent.json's entries that only a resume reads (the aggregate data file's record, the RNG states): a shipped
# student leaves them out, as it leaves out the data file
RESUME_ENTRIES = ("data", "rng", "torch_generator")


class NumpyStudent:
    """observation -> action, from the layers (weights, biases) and the normaliser: tanh after every layer."""

    def __init__(self, layers: list[tuple[np.ndarray, np.ndarray]], mean: np.ndarray, std: np.ndarray):
        self.layers, self.mean, self.std = layers, mean, std

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        h = (np.asarray(observation, np.float64) - self.mean) / self.std
        for weights, bias in self.layers:
            h = np.tanh(weights @ h + bias)
        return h.astype(np.float32)

    def save(self, folder: Path) -> str:
        """Write student.npz and student.json to `folder`, each whole; returns student.npz's sha256."""
        arrays: dict[str, Any] = {}
        for i, (weights, bias) in enumerate(self.layers):
            arrays[f"W{i}"], arrays[f"b{i}"] = weights, bias
        buffer = _npz_bytes(arrays)
        write_bytes_atomic(folder / WEIGHTS_FILE, buffer)
        sizes = [int(self.layers[0][0].shape[1])] + [int(w.shape[0]) for w, _ in self.layers]
        write_json_atomic(folder / ARCHITECTURE_FILE, {
            "format": ARCHITECTURE_FORMAT, "sizes": sizes, "activation": "tanh", "output_activation": "tanh",
            "normaliser": {"mean": self.mean.tolist(), "std": self.std.tolist()}})
        return hashlib.sha256(buffer).hexdigest()

    @classmethod
    def load(cls, folder: Path, sha256: str | None = None) -> NumpyStudent:
        """The student saved in `folder`; RunFileError naming the file if it is not one (or not the checkpoint's)."""
        weights_path, architecture_path = folder / WEIGHTS_FILE, folder / ARCHITECTURE_FILE
        try:
            architecture = json.loads(architecture_path.read_text(encoding="utf-8"))
            if architecture.get("format") != ARCHITECTURE_FORMAT:
                raise ValueError(f"format {architecture.get('format')!r}, not {ARCHITECTURE_FORMAT!r}")
            sizes = [int(n) for n in architecture["sizes"]]
            mean = np.array(architecture["normaliser"]["mean"], np.float64)
            std = np.array(architecture["normaliser"]["std"], np.float64)
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise RunFileError(f"{architecture_path}: not a student's architecture ({error})") from None
        try:
            data = weights_path.read_bytes()
            if sha256 is not None and hashlib.sha256(data).hexdigest() != sha256:
                raise ValueError("not the weights the checkpoint recorded (sha256 differs)")
            with np.load(weights_path, allow_pickle=False) as arrays:
                layers = [(arrays[f"W{i}"].astype(np.float64), arrays[f"b{i}"].astype(np.float64))
                          for i in range(len(sizes) - 1)]
        except (OSError, ValueError, KeyError) as error:
            raise RunFileError(f"{weights_path}: not the student's weights ({error})") from None
        shapes = [(w.shape, b.shape) for w, b in layers]
        inputs = (sizes[0],)
        if shapes != [((n, m), (n,)) for m, n in zip(sizes, sizes[1:])] or mean.shape != inputs or std.shape != inputs:
            raise RunFileError(f"{weights_path}: the weights' shapes {shapes} do not fit {architecture_path}'s sizes "
                               f"{sizes}")
        return cls(layers, mean, std)


def _npz_bytes(arrays: dict[str, Any]) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def greedy_policy(run: LoadedRun, checkpoint: dict[str, Any]) -> Any:
    """Agent bc_dagger's loader (robot_rl.agents.registry): the student saved beside the checkpoint, which must fit
    the env it plays in (its observation's size)."""
    if checkpoint.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{run.path}: not a bc_dagger checkpoint (format {checkpoint.get('format')!r})")
    student = NumpyStudent.load(run.path.parent, checkpoint.get("weights_sha256"))

    def policy(env: Any, _seed: int) -> NumpyStudent:
        size = int(np.prod(env.observation_space.shape))
        if student.mean.shape != (size,):
            raise ValueError(f"{run.path}: the student takes {student.mean.shape[0]} inputs, the env observes {size}")
        return student
    return policy
