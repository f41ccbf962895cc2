"""Inference: a PCNBV copy with batch norm folded, in float32 its attention and first wide conv
rewritten with fewer FLOPs (in bfloat16 its wide weights stored in bfloat16), and the choice of
the best unvisited view from predicted gains."""

from __future__ import annotations

import copy
import math

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from nbv.models.layers import Pointwise, max_over
from nbv.models.pcnbv import PCNBV, check_inputs
from nbv.models.precision import in_float32, resolve_precision


class InferencePCNBV(nn.Module):
    """A PCNBV rewritten for float32 evaluation-mode forwards: the same function, 23 % fewer
    FLOPs (:func:`for_inference` builds it; bfloat16 keeps the network's own form).

    In :class:`~nbv.models.pcnbv.PCNBV` the attention and the first wide 1x1 conv read the
    concatenation ``x_i = [p_i, g, s]`` of a point's features ``p_i`` (P channels), the global
    max ``g`` and the view state ``s``, the last two the same for every point. Their products
    split by those parts (``W x_i = W_p p_i + W_g g + W_s s``), and so, exactly in real
    arithmetic:

    - the query is ``Q_p p_i + c_q`` with ``c_q`` computed once a sample;
    - the key's constant part adds ``q_i . c_k`` to every score of row ``i``, which the softmax
      over ``j`` removes: the key is ``K_p p_j``;
    - the rows of the attention ``A`` sum to one, so ``sum_j A_ij v_j = V_p (A P)_i + c_v``:
      the value product (561 x 561 a point) becomes ``A P`` (P = 264 channels a point);
    - the first conv (batch norm folded) of ``gamma (A V)_i + x_i`` is
      ``[gamma W V_p, W_p] [(A P)_i; p_i] + c_1``, one product of 2P = 528 input channels
      instead of 561 after a 561-channel value, with the per-sample ``c_1`` folded from the
      value's and the conv's ``g`` and ``s`` parts.

    At 512 points that is 2.01 GFLOP a forward instead of 2.61 (:func:`nbv.bench.floor.
    inference_flops`). Rounding differs from the original's: on the shipped weights the float32
    outputs agree with the batch-norm-folded network's to 3e-8, and the default evaluation's
    10,096 episodes picked the same views. The feature extractor, the further 1x1 convs and
    the head are the original's (batch norm folded).

    ``forward(points (B, N, 3), view_state (B, V)) -> (B, V)`` as :meth:`PCNBV.forward`.
    """

    def __init__(self, model: PCNBV) -> None:
        super().__init__()
        cfg = self.config = model.config
        self.features, self.head = model.features, model.head
        self.convs = model.convs[1:]
        attention, first = model.attention, model.convs[0].linear
        p = cfg.point_channels
        dtype = attention.gamma.dtype  # float32, or float64 for an exactness check
        f64 = {"dtype": torch.float64}
        gamma = attention.gamma.to(**f64)
        w_q, w_v, w_1 = (m.weight.to(**f64) for m in (attention.query, attention.value, first))
        w_1v = gamma * w_1 @ w_v  # the first conv of the attention's gamma-scaled values
        b_1 = gamma * w_1 @ attention.value.bias.to(**f64) + first.bias.to(**f64)

        def buffer(name: str, value: Tensor) -> None:
            self.register_buffer(name, value.to(dtype).contiguous())

        buffer("query_points", w_q[:, :p])
        buffer("query_rest", w_q[:, p:])  # (A, P + V): the g and s parts, per sample
        buffer("query_bias", attention.query.bias)
        buffer("key_points", attention.key.weight[:, :p])
        buffer("conv_points", torch.cat([w_1v[:, :p], w_1[:, :p]], dim=1))
        buffer("conv_rest", w_1v[:, p:] + w_1[:, p:])
        buffer("conv_bias", b_1)
        self.requires_grad_(False)

    def forward(self, points: Tensor, view_state: Tensor) -> Tensor:
        check_inputs(self.config, self.query_rest.dtype, points, view_state)
        if self.config.normalize_input:
            points = PCNBV.normalize(points)
        per_point = self.features(points)
        with in_float32(per_point):  # the per-sample constants: (B, P + V) products, cheap
            rest = torch.cat([max_over(per_point, 1), view_state.to(per_point.dtype)], dim=1)
            query_shift = F.linear(rest, self.query_rest, self.query_bias).unsqueeze(1)
            conv_shift = F.linear(rest, self.conv_rest, self.conv_bias).unsqueeze(1)
        p = per_point.to(self.query_points.dtype)
        query = F.linear(p, self.query_points).add_(query_shift)
        attention = torch.softmax(query @ F.linear(p, self.key_points).transpose(1, 2), dim=-1)
        both = torch.cat([attention.to(p.dtype) @ p, p], dim=-1)
        x = F.relu(F.linear(both, self.conv_points).add_(conv_shift), inplace=True)
        x = max_over(self.convs(x), 1)
        with in_float32(x):
            return self.head(x.to(points.dtype))


def for_inference(model: PCNBV, precision: str = "fp32") -> PCNBV | InferencePCNBV:
    """A copy of ``model`` for fast evaluation-mode forwards: the same predictions, less work.

    Batch norm is folded into the 1x1 conv before it (in eval mode it is an affine map per
    channel). In float32 the attention and the first wide conv are then rewritten as
    :class:`InferencePCNBV` says. For ``"bf16"`` (``"auto"`` resolved on the model's device)
    the network keeps its form and the weights of the attention and of the wide 1x1 convs are
    stored in bfloat16, so autocast does not cast them again on every call; the feature
    extractor and the head, which run in float32, keep float32 weights. Parameters do not
    require grad.

    Args:
        model: a PCNBV, not modified.
        precision: a :data:`PRECISIONS` name; run the copy under :func:`autocast` with it.
            Another declared network (:mod:`nbv.models.networks`) is copied as it is.

    Returns:
        The copy, in eval mode, on the model's device.
    """
    device = next(model.parameters()).device
    bf16 = resolve_precision(precision, device) == "bf16"
    out = copy.deepcopy(model).eval().requires_grad_(False)
    if not isinstance(model, PCNBV):  # another declared network runs as it is
        return out
    for module in out.modules():
        if isinstance(module, Pointwise) and module.norm is not None:
            norm, old = module.norm, module.linear
            scale = norm.weight / torch.sqrt(norm.running_var + norm.eps)
            bias = old.bias if old.bias is not None else torch.zeros_like(norm.running_mean)
            fused = nn.Linear(
                old.in_features, old.out_features, device=device, dtype=old.weight.dtype
            )
            with torch.no_grad():
                fused.weight.copy_(old.weight * scale[:, None])
                fused.bias.copy_((bias - norm.running_mean) * scale + norm.bias)
            module.linear, module.norm = fused.requires_grad_(False), None
    if not bf16:
        return InferencePCNBV(out).eval()
    # bfloat16 keeps the network's own form: the rewritten one rounds its three significant
    # digits at other places, which flipped the pick of 65 of the default evaluation's 10,096
    # episodes (PCNBV-sph's AUC by 0.0008), and its tables were made with this one.
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
