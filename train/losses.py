"""Training losses of the per-view gain networks.

* ``squared`` (the paper's): the sum over the V outputs of the squared error against the raw
  gains, mean over the batch. The large gains of a trajectory's first steps dominate it: its late
  steps (2-9, 80 % of the samples) carry under 0.4 % of it.
* ``normalised`` (the default of ``python -m train``): the same on targets divided by the sample's
  largest gain, so that every sample's ranking weighs alike (a sample without gain, all 0, stays
  0).
* ``listwise``: softmax cross-entropy over the unvisited views, the outputs as logits, against the
  gains normalised to sum to 1: the network learns which views gain most relative to the others,
  not the gains' scale. Samples without gain take no part. The outputs are then scores, not gains;
  the best view is still their argmax.
* ``pairwise``: RankNet's logistic loss over every ordered pair of unvisited views,
  ``log(1 + exp(-(s_i - s_j)))`` for each pair whose true gains order ``i`` above ``j``, averaged
  over the sample's pairs. Every pair weighs alike, as in the rank correlation the training
  reports; the listwise loss instead weighs the views by their share of the gain. It depends on
  the gains only through their order. Samples whose unvisited views all gain alike take no part.

The weight penalty added to the loss (``l2`` times :func:`weight_penalty`) takes every weight
matrix or the point encoder's alone (``l2_scope``, :func:`penalised`).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from train.config import L2_SCOPES, LOSSES

__all__ = ["L2_SCOPES", "LOSSES", "batch_loss", "penalised", "per_sample_loss", "weight_penalty"]


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
    if name == "pairwise":
        above = _ordered_pairs(target, view_state)
        # softplus(-(s_i - s_j)) = log(1 + exp(-(s_i - s_j))), without overflow.
        pair_loss = F.softplus(pred[:, None, :] - pred[:, :, None])
        return (pair_loss * above).sum(dim=(1, 2)) / above.sum(dim=(1, 2)).clamp_min(1)
    raise ValueError(f"loss={name!r}: must be one of {', '.join(LOSSES)}")


def _ordered_pairs(target: torch.Tensor, view_state: torch.Tensor) -> torch.Tensor:
    """(B, V, V) float: 1 where views ``i`` and ``j`` are both unvisited and ``i`` gains more."""
    open_ = view_state < 0.5
    both = open_[:, :, None] & open_[:, None, :]
    return ((target[:, :, None] > target[:, None, :]) & both).float()


def _counted(name: str, target: torch.Tensor, view_state: torch.Tensor) -> torch.Tensor | None:
    """(B,) bool: the samples a ranking loss learns from (None: every sample counts)."""
    if name == "listwise":
        return (torch.where(view_state < 0.5, target, torch.zeros_like(target)) > 0).any(dim=1)
    if name == "pairwise":
        return _ordered_pairs(target, view_state).flatten(1).any(dim=1)
    return None


def batch_loss(
    name: str, pred: torch.Tensor, target: torch.Tensor, view_state: torch.Tensor
) -> torch.Tensor:
    """Mean of :func:`per_sample_loss` over the batch (for ``listwise`` over the samples with
    gain, for ``pairwise`` over those with two unvisited views of different gains); a scalar
    tensor."""
    losses = per_sample_loss(name, pred, target, view_state)
    counted = _counted(name, target, view_state)
    if counted is None:
        return losses.mean()
    return (losses * counted).sum() / counted.sum().clamp_min(1)


def penalised(model: nn.Module, scope: str) -> list[str]:
    """Names of the parameters the L2 penalty takes: the weight matrices (ndim > 1) of the
    whole network (``scope="all"``) or of its point encoder, everything but the fully
    connected ``head`` of :class:`nbv.models.pcnbv.PCNBV` (``scope="encoder"``).

    Raises:
        ValueError: an unknown scope.
    """
    if scope not in L2_SCOPES:
        raise ValueError(f"l2_scope={scope!r}: must be one of {', '.join(L2_SCOPES)}")
    return [
        name
        for name, p in model.named_parameters()
        if p.ndim > 1 and (scope == "all" or not name.startswith("head."))
    ]


def weight_penalty(model: nn.Module, scope: str) -> torch.Tensor:
    """The sum of the squares of the :func:`penalised` parameters (a scalar tensor)."""
    names = set(penalised(model, scope))
    return sum((p**2).sum() for n, p in model.named_parameters() if n in names)
