"""PPO's observations normalised inside its network: each value's running mean and variance over the rollouts
so far, as torch buffers of the policy (agent param normalise_observations).

Why in the network and not SB3's VecNormalize: the statistics are then part of the policy's weights, so model.zip
carries them (written and read as tensors, never pickled), and every loader of a run's weights (resume, evaluate.py,
the video, a shipped policy) normalises as training did without a file or a wrapper more.

- `RunningNormaliser`: SB3's features extractor; (observation - mean) / sqrt(var + 1e-8), clipped to +/- `clip`
  (VecNormalize's defaults). At the start mean 0 and variance 1: the identity.
- `NormaliserUpdates`: the callback that folds each rollout's observations into the statistics after PPO's update
  on that rollout, before the next one is collected: a rollout is collected and learned from with the same
  statistics (PPO's probability ratios compare one function), as VecNormalize's stored observations are. The last
  rollout of a run (or of a run's part before a resume) is learned from but not folded in.
"""
from __future__ import annotations

import gymnasium
import numpy as np
import torch
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

VARIANCE_FLOOR = 1e-8
START_COUNT = 1e-4  # the weight of the start's mean 0 and variance 1 (VecNormalize's epsilon)


class RunningNormaliser(BaseFeaturesExtractor):
    """A Box observation, flattened and normalised by the running statistics `mean`, `var` and `count` (buffers:
    saved and loaded with the policy's weights)."""

    mean: torch.Tensor
    var: torch.Tensor
    count: torch.Tensor

    def __init__(self, observation_space: gymnasium.spaces.Box, clip: float = 10.0):
        size = int(np.prod(observation_space.shape))
        super().__init__(observation_space, features_dim=size)
        self.clip = clip
        self.register_buffer("mean", torch.zeros(size, dtype=torch.float64))
        self.register_buffer("var", torch.ones(size, dtype=torch.float64))
        self.register_buffer("count", torch.tensor(START_COUNT, dtype=torch.float64))

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        flat = torch.flatten(observations, start_dim=1)
        scale = torch.sqrt(self.var + VARIANCE_FLOOR).to(flat.dtype)
        return torch.clamp((flat - self.mean.to(flat.dtype)) / scale, -self.clip, self.clip)

    @torch.no_grad()
    def update(self, batch: np.ndarray) -> None:
        """Fold a batch of observations (any leading shape) into the statistics (Chan et al.'s parallel merge)."""
        values = np.asarray(batch, np.float64).reshape(-1, self.mean.numel())
        if not len(values):
            return
        n, batch_mean, batch_var = len(values), values.mean(axis=0), values.var(axis=0)
        mean, var, count = self.mean.numpy(), self.var.numpy(), float(self.count)
        total = count + n
        delta = batch_mean - mean
        merged_var = (var * count + batch_var * n + delta * delta * count * n / total) / total
        self.mean.copy_(torch.from_numpy(mean + delta * n / total))
        self.var.copy_(torch.from_numpy(merged_var))
        self.count.fill_(total)


class NormaliserUpdates(BaseCallback):
    """Folds each of PPO's rollouts into its policy's `RunningNormaliser` once PPO has learned from it."""

    def __init__(self) -> None:
        super().__init__()
        self.pending: np.ndarray | None = None

    def _on_rollout_end(self) -> None:
        assert isinstance(self.model, OnPolicyAlgorithm)
        self.pending = np.array(self.model.rollout_buffer.observations, copy=True)  # PPO trains on it next

    def _on_rollout_start(self) -> None:  # after that update: the buffer was emptied for the next rollout
        if self.pending is not None:
            normaliser = self.model.policy.features_extractor
            assert isinstance(normaliser, RunningNormaliser)
            normaliser.update(self.pending)
            self.pending = None

    def _on_step(self) -> bool:
        return True
