"""Inference: a PCNBV copy with batch norm folded (and bfloat16 weights), and the choice of
the best unvisited view from predicted gains."""

from __future__ import annotations

import copy
import math

import torch
from torch import Tensor, nn

from nbv.models.layers import Pointwise
from nbv.models.pcnbv import PCNBV
from nbv.models.precision import resolve_precision


def for_inference(model: PCNBV, precision: str = "fp32") -> PCNBV:
    """A copy of ``model`` for fast evaluation-mode forwards: the same predictions, less work.

    Batch norm is folded into the 1x1 conv before it (in eval mode it is an affine map per
    channel), and for ``"bf16"`` (``"auto"`` resolved on the model's device) the weights of the
    attention and of the wide 1x1 convs are stored in bfloat16, so autocast does not cast them
    again on every call; the feature extractor and the head, which run in float32, keep float32
    weights. Parameters do not require grad.

    Args:
        model: a PCNBV, not modified.
        precision: a :data:`PRECISIONS` name; run the copy under :func:`autocast` with it.

    Returns:
        The copy, in eval mode, on the model's device.
    """
    device = next(model.parameters()).device
    bf16 = resolve_precision(precision, device) == "bf16"
    out = copy.deepcopy(model).eval().requires_grad_(False)
    for module in out.modules():
        if isinstance(module, Pointwise) and module.norm is not None:
            norm, old = module.norm, module.linear
            scale = norm.weight / torch.sqrt(norm.running_var + norm.eps)
            bias = old.bias if old.bias is not None else torch.zeros_like(norm.running_mean)
            fused = nn.Linear(old.in_features, old.out_features, device=device)
            with torch.no_grad():
                fused.weight.copy_(old.weight * scale[:, None])
                fused.bias.copy_((bias - norm.running_mean) * scale + norm.bias)
            module.linear, module.norm = fused.requires_grad_(False), None
    if bf16:
        for name, module in out.named_modules():
            if isinstance(module, nn.Linear) and name.split(".")[0] in ("attention", "convs"):
                module.to(torch.bfloat16)
    return out


def masked_argmax(scores: Tensor, view_state: Tensor) -> Tensor:
    """The best unvisited view of each sample.

    Args:
        scores: (B, V) float predicted gains (no NaN); ``-inf`` is allowed.
        view_state: (B, V) bool or 0/1, 1 = visited.

    Returns:
        (B,) int64 index of the highest-scoring unvisited view (the first one on ties).

    Raises:
        ValueError: shapes differ, a score is NaN, or a sample has no unvisited view.
    """
    if scores.ndim != 2 or scores.shape != view_state.shape:
        raise ValueError(
            f"scores and view_state must both have shape (B, V), got {tuple(scores.shape)} "
            f"and {tuple(view_state.shape)}"
        )
    visited = view_state.to(torch.bool)
    full = visited.all(dim=1)
    if full.any():
        raise ValueError(
            f"no unvisited view left in samples {full.nonzero().flatten().tolist()}; "
            "view_state is all ones there"
        )
    if torch.isnan(scores).any():
        raise ValueError("scores contain NaN")
    best = scores.masked_fill(visited, -math.inf).argmax(dim=1)
    # When every unvisited score is -inf, argmax may land on a visited view: take the first
    # unvisited one instead.
    stuck = visited.gather(1, best.unsqueeze(1)).squeeze(1)
    return torch.where(stuck, (~visited).to(torch.uint8).argmax(dim=1), best)
