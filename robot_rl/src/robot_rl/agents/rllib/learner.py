"""Agent rllib_ppo's Learner: RLlib's PPOTorchLearner with the per-minibatch bookkeeping of its gradients fused.

The loss, the minibatches, the optimiser and its step are RLlib's, unchanged. Two of RLlib's steps after the backward
pass loop over the gradient tensors one by one, and at rllib_ppo's small MLPs (minibatches of 64, a few thousand
weights) those per-tensor calls are a visible part of an update (12 % and 7 % of it in a py-spy profile):
- clipping by global norm: RLlib's `clip_gradients` takes one norm per tensor, then scales each; here one
  `_foreach_norm` and one `_foreach_mul_` do the same (the same norm, its nan/inf replaced as RLlib does, and the
  same coefficient: grad_clip / max(norm + 1e-6, grad_clip), at most 1);
- applying: RLlib checks every tensor for nan/inf (one host sync per tensor) to make it finite (`torch.nan_to_num`),
  then checks every tensor again before stepping; here one check of all of them (of their norms: finite only when
  every entry is), the same `nan_to_num` on all when it fails (a no-op on finite tensors), then the step.
Where RLlib's other paths are configured (learning-rate schedulers, grad scalers, torch_skip_nan_gradients) or
clipping is not by global norm, RLlib's own methods run. It takes 2-20 % off the driver's update
(docs/research/2026-11-29-rllib-lean-learner.md).
"""
from __future__ import annotations

import logging
from typing import Any

import torch
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.utils.torch_utils import clip_gradients

logger = logging.getLogger(__name__)


def clip_by_global_norm(gradients_dict: dict[Any, torch.Tensor], *, grad_clip: float | None = None,
                        grad_clip_by: str = "value") -> Any:
    """RLlib's `clip_gradients` (in place, the global norm returned), fused for grad_clip_by "global_norm"."""
    if grad_clip is None or grad_clip_by != "global_norm":
        return clip_gradients(gradients_dict, grad_clip=grad_clip, grad_clip_by=grad_clip_by)
    gradients = [g.detach() for g in gradients_dict.values() if g is not None]
    if not gradients:
        return torch.tensor(0.0)
    norms = torch.stack(torch._foreach_norm(gradients, 2.0))
    norm = torch.linalg.vector_norm(norms.nan_to_num(neginf=-10e8, posinf=10e8)).nan_to_num(neginf=-10e8, posinf=10e8)
    coefficient = torch.clamp(grad_clip / torch.clamp(norm + 1e-6, min=grad_clip), max=1.0)
    torch._foreach_mul_(gradients, coefficient)
    return norm


class LeanPPOTorchLearner(PPOTorchLearner):
    """PPOTorchLearner whose gradient clipping and application are fused over the tensors (module docstring)."""

    @staticmethod
    def _get_clip_function() -> Any:
        return clip_by_global_norm

    def apply_gradients(self, gradients_dict: dict[Any, torch.Tensor]) -> None:
        if self._lr_scheduler_classes is not None or self._grad_scalers is not None \
                or self.config.torch_skip_nan_gradients:
            return super().apply_gradients(gradients_dict)
        gradients = list(gradients_dict.values())
        if gradients and not bool(torch.isfinite(torch.stack(torch._foreach_norm(gradients, 2.0))).all()):
            logger.warning("Gradients contain `nan/inf` values: setting them to finite values (torch.nan_to_num), "
                           "as RLlib does.")
            gradients = [torch.nan_to_num(g) for g in gradients]
        for pid, gradient in zip(gradients_dict, gradients):
            self._params[pid].grad = gradient
        for module_id, optimizer_names in self._module_optimizers.items():
            for optimizer_name in optimizer_names:
                self.get_optimizer(module_id, optimizer_name).step()
        return None
