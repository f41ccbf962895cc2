"""Training losses of the per-view gain networks.

* ``squared`` (the paper's, the default): the sum over the V outputs of the squared error against
  the raw gains, mean over the batch. The large gains of a trajectory's first steps dominate it.
* ``normalised``: the same on targets divided by the sample's largest gain, so that every sample's
  ranking weighs alike (a sample without gain, all 0, stays 0).
* ``listwise``: softmax cross-entropy over the unvisited views, the outputs as logits, against the
  gains normalised to sum to 1: the network learns which views gain most relative to the others,
  not the gains' scale. Samples without gain take no part. The outputs are then scores, not gains;
  the best view is still their argmax.
"""

from __future__ import annotations

import torch

from train.config import LOSSES

__all__ = ["LOSSES", "batch_loss", "per_sample_loss"]


def _normalised(target: torch.Tensor) -> torch.Tensor:
    top = target.amax(dim=1, keepdim=True)
    return torch.where(top > 0, target / top.clamp_min(1e-12), target)


def per_sample_loss(
    name: str, pred: torch.Tensor, target: torch.Tensor, view_state: torch.Tensor
) -> torch.Tensor:
    """(B,) loss of each sample (0 for a ``listwise`` sample without gain).

    Args:
        name: one of :data:`LOSSES`.
        pred: (B, V) network outputs.
        target: (B, V) true gains, 0 for visited views.
        view_state: (B, V) 1 = visited.

    Raises:
        ValueError: an unknown name.
    """
    pred = pred.float()
    if name == "squared":
        return ((pred - target) ** 2).sum(dim=1)
    if name == "normalised":
        return ((pred - _normalised(target)) ** 2).sum(dim=1)
    if name == "listwise":
        open_ = view_state < 0.5
        gains = torch.where(open_, target.clamp_min(0), torch.zeros_like(target))
        total = gains.sum(dim=1, keepdim=True)
        weights = gains / total.clamp_min(1e-12)
        logits = pred.masked_fill(~open_, float("-inf"))
        log_p = torch.log_softmax(logits, dim=1).masked_fill(~open_, 0.0)
        return -(weights * log_p).sum(dim=1)
    raise ValueError(f"loss={name!r}: must be one of {', '.join(LOSSES)}")


def batch_loss(
    name: str, pred: torch.Tensor, target: torch.Tensor, view_state: torch.Tensor
) -> torch.Tensor:
    """Mean of :func:`per_sample_loss` over the batch (over the samples with gain for
    ``listwise``); a scalar tensor."""
    losses = per_sample_loss(name, pred, target, view_state)
    if name == "listwise":
        counted = (torch.where(view_state < 0.5, target, torch.zeros_like(target)) > 0).any(dim=1)
        return (losses * counted).sum() / counted.sum().clamp_min(1)
    return losses.mean()
