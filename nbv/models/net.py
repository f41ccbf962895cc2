"""PCNBV: the point-cloud next-best-view network, and its checkpoints.

The network reads a point cloud and the view state and predicts, for each of the ``V`` candidate
views, the coverage gain that view would add. It follows the architecture described in
``FACTS.md`` (PC-NBV, Zeng et al. 2020, with the PyTorch port's batch norm and input
normalisation); the same class serves PCNBV-sph, whose input points are the spherical-signature
points instead of the accumulated cloud.

Data flow for one sample (``C`` = channels, defaults in brackets)::

    points (N, 3) ──normalise──► 1x1 conv 3 -> 24 ──► 4 dense EdgeConv blocks ──► (N, 264)
    concat[per-point (264), global max (264) tiled, view state (V) tiled] ──► (N, 561)
    self-attention (N, 561) ──► 1x1 convs 561 -> 1024 -> 1024 ──► max over points (1024)
    fully connected 1024 -> 512 -> 256 -> V (linear output)

Internally features are laid out points-last-but-one, ``(B, N, C)``, so every "1x1 conv" is a
single matrix product (``nn.Linear``) over the channel axis.

Precision: forward passes may run under bfloat16 autocast (:func:`autocast`, ``"bf16"``), which
CPUs with AMX or AVX512-BF16 run 1.3-1.5x faster than float32. Only the self-attention and the
wide 1x1 convs use it. The dense EdgeConv feature extractor (with its neighbour search) and the
fully connected head stay in float32: neighbour ranks and the small differences between views'
predicted gains are what the output is used for, bfloat16 keeps only about three significant
digits, and the extractor's narrow products gain nothing from it.

Public API: :class:`PCNBVConfig`, :class:`PCNBV`, :func:`masked_argmax`,
:func:`count_parameters`, :func:`save_checkpoint`, :func:`load_checkpoint`,
:class:`CheckpointError`, :data:`PRECISIONS`, :func:`resolve_precision`, :func:`autocast`,
:func:`flush_denormals`, :func:`for_inference`.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import math
import os
import tempfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F
from torch import Tensor, nn

#: Written into every checkpoint so that foreign files are recognised.
CHECKPOINT_FORMAT = "nbv.models.net.PCNBV"
#: Bumped when the checkpoint layout changes incompatibly.
CHECKPOINT_VERSION = 1
#: Arithmetic of forward passes: ``"auto"`` (bf16 where the hardware runs it natively, else
#: fp32), ``"fp32"`` or ``"bf16"`` (bfloat16 autocast).
PRECISIONS = ("auto", "fp32", "bf16")


def resolve_precision(precision: str, device: torch.device | str = "cpu") -> str:
    """``"fp32"`` or ``"bf16"`` for a :data:`PRECISIONS` name on ``device``.

    ``"auto"`` is ``"bf16"`` on a CPU with AMX tiles or AVX512-BF16 instructions and on a CUDA
    device that supports bfloat16; elsewhere bfloat16 would be emulated (slower than float32),
    so it is ``"fp32"``.

    Raises:
        ValueError: an unknown name.
    """
    if precision not in PRECISIONS:
        raise ValueError(f"precision={precision!r}: must be one of {', '.join(PRECISIONS)}")
    if precision != "auto":
        return precision
    kind = torch.device(device).type
    if kind == "cuda":
        return "bf16" if torch.cuda.is_bf16_supported() else "fp32"
    if kind == "cpu" and (
        torch.cpu._is_amx_tile_supported() or torch.cpu._is_avx512_bf16_supported()
    ):
        return "bf16"
    return "fp32"


def autocast(
    precision: str, device: torch.device | str = "cpu"
) -> contextlib.AbstractContextManager:
    """The context a forward (and backward) pass runs in for ``precision`` on ``device``:
    bfloat16 autocast for ``"bf16"`` (``"auto"`` resolved by :func:`resolve_precision`),
    nothing for ``"fp32"``."""
    kind = torch.device(device).type
    enabled = resolve_precision(precision, device) == "bf16"
    return torch.autocast(kind, dtype=torch.bfloat16, enabled=enabled)


@contextlib.contextmanager
def flush_denormals() -> Iterator[None]:
    """Treat subnormal floats as zero on the CPU inside the block (FTZ/DAZ), then restore the
    state it found (so an inner block does not switch off an outer one's flushing).

    Trained weights make some activations subnormal, and x86 CPUs compute on those up to 100
    times slower: a trained PCNBV ran 3x slower than a fresh one in float32 (120 ms against
    40 ms a forward at 512 points). Values below 1e-38 change no prediction.
    """
    # torch has no getter for the flag: a subnormal times one is zero exactly when it is on.
    was_on = float(torch.tensor([1e-40]) * 1.0) == 0.0
    supported = torch.set_flush_denormal(True)
    try:
        yield
    finally:
        if supported and not was_on:
            torch.set_flush_denormal(False)


def _float32(x: Tensor) -> contextlib.AbstractContextManager:
    """A context with autocast off on ``x``'s device (its float32 region)."""
    return torch.autocast(x.device.type, enabled=False)


@dataclass(frozen=True)
class PCNBVConfig:
    """Sizes of a :class:`PCNBV` network. The defaults are PC-NBV's (264 channels a point, 561
    after concatenation with 33 views).

    Attributes:
        n_views: V, the number of candidate views (length of the view state and the output).
        k: neighbours of each point in a dense EdgeConv block (the point itself included).
        growth: channels each dense layer adds.
        dense_layers: layers in a dense block.
        blocks: dense blocks in the feature extractor.
        first_channels: width of the first 1x1 conv and the input width of every dense block.
        attention_channels: width of the attention query and key.
        conv_channels: widths of the 1x1 convs after the attention.
        fc_channels: widths of the hidden fully connected layers.
        batch_norm: batch norm after every hidden conv (the PyTorch port's choice); without it
            the convs carry a bias instead.
        normalize_input: centre each cloud at its centroid and scale it to unit max radius.
            Turn it off for inputs whose position and scale carry information.
    """

    n_views: int = 33
    k: int = 16
    growth: int = 12
    dense_layers: int = 3
    blocks: int = 4
    first_channels: int = 24
    attention_channels: int = 140
    conv_channels: tuple[int, ...] = (1024, 1024)
    fc_channels: tuple[int, ...] = (512, 256)
    batch_norm: bool = True
    normalize_input: bool = True

    def __post_init__(self) -> None:
        for name in (
            "n_views",
            "k",
            "growth",
            "dense_layers",
            "blocks",
            "first_channels",
            "attention_channels",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"PCNBVConfig.{name} must be a positive int, got {value!r}")
        for name in ("conv_channels", "fc_channels"):
            value = getattr(self, name)
            if not isinstance(value, tuple | list) or not all(
                isinstance(c, int) and not isinstance(c, bool) and c >= 1 for c in value
            ):
                raise ValueError(
                    f"PCNBVConfig.{name} must be a sequence of positive ints, got {value!r}"
                )
            # Lists come back from checkpoints and hydra; store a tuple so configs compare equal.
            object.__setattr__(self, name, tuple(value))
        if not self.conv_channels:
            raise ValueError("PCNBVConfig.conv_channels must hold at least one width, got ()")
        for name in ("batch_norm", "normalize_input"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"PCNBVConfig.{name} must be a bool, got {getattr(self, name)!r}")

    @property
    def block_out_channels(self) -> int:
        """Channels a dense block outputs: ``dense_layers * growth + first_channels`` (60)."""
        return self.dense_layers * self.growth + self.first_channels

    @property
    def point_channels(self) -> int:
        """Channels a point has after the feature extractor (264)."""
        return self.first_channels + self.blocks * self.block_out_channels

    @property
    def concat_channels(self) -> int:
        """Channels a point has after concatenating global feature and view state (561)."""
        return 2 * self.point_channels + self.n_views

    def to_dict(self) -> dict[str, Any]:
        """Plain-type dict (lists for tuples) that :meth:`from_dict` reads back."""
        return {
            f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v
            for f in dataclasses.fields(self)
        }

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> PCNBVConfig:
        """Build a config from :meth:`to_dict`'s output; unknown keys raise ``ValueError``."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ValueError(f"unknown PCNBVConfig keys {unknown}; allowed: {sorted(names)}")
        return cls(**dict(values))


class _Pointwise(nn.Module):
    """Shared ``Linear`` over the last axis (a 1x1 conv), optional batch norm over every other
    position, ReLU: ``(..., C_in) -> (..., C_out)``."""

    def __init__(self, c_in: int, c_out: int, batch_norm: bool) -> None:
        super().__init__()
        self.linear = nn.Linear(c_in, c_out, bias=not batch_norm)
        self.norm = nn.BatchNorm1d(c_out) if batch_norm else None

    def activate(self, y: Tensor) -> Tensor:
        """Batch norm and ReLU of a pre-activation ``y`` (..., C_out); may reuse its memory."""
        if self.norm is not None:
            y = self.norm(y.reshape(-1, y.shape[-1])).reshape(y.shape)
        return F.relu(y, inplace=True)

    def forward(self, x: Tensor) -> Tensor:
        return self.activate(self.linear(x))


def max_over(x: Tensor, dim: int, keepdim: bool = False) -> Tensor:
    """``x.amax(dim)``, but through ``max(dim).values`` when a gradient is needed: its backward
    (a scatter to the arg-max) costs about half of ``amax``'s, while ``amax`` is the faster of
    the two without autograd. Same values either way."""
    if x.requires_grad and torch.is_grad_enabled():
        return x.max(dim=dim, keepdim=keepdim).values
    return x.amax(dim=dim, keepdim=keepdim)


def knn_indices(x: Tensor, k: int) -> Tensor:
    """Indices of the ``k`` nearest neighbours of every point in feature space, the point itself
    always included (its distance is forced to ``-inf``, so rounding cannot push it out).

    Args:
        x: (B, N, C) float features; ``k <= N``.
        k: neighbours per point, self included.

    Returns:
        (B, N, k) int64 indices into the N axis, in no particular order; not differentiable.
    """
    with torch.no_grad(), _float32(x):
        x = x.float()
        n = x.shape[1]
        # On the CPU a few samples at a time, so that their distance tables stay in the cache
        # through the selection: training's neighbour search ran 45% faster (32 x 512 points).
        group = max(1, _CACHED_DISTANCES // (n * n)) if x.device.type == "cpu" else len(x)
        return torch.cat([_nearest(part, k) for part in x.split(group)])


#: Float32 distances (4 MB) a group of samples of :func:`knn_indices` holds at a time on the CPU.
_CACHED_DISTANCES = 2**20


def _nearest(x: Tensor, k: int) -> Tensor:
    """:func:`knn_indices` of float32 features ``x`` (B, N, C), all at once."""
    # |x_i - x_j|^2 minus the |x_i|^2 term, which is the same along a row, so ranks agree.
    sq = (x * x).sum(-1).unsqueeze(1)
    dist = torch.baddbmm(sq, x, x.transpose(1, 2), alpha=-2.0)
    dist.diagonal(dim1=1, dim2=2).fill_(-math.inf)
    return smallest_indices(dist, k)


def smallest_indices(values: Tensor, k: int, chunk: int = 16) -> Tensor:
    """Indices of the ``k`` smallest entries of every row: ``values.topk(k, largest=False,
    sorted=False).indices`` (the same set; among ties, any), in a fifth to a third less time
    on a few 512-wide tables on the CPU. Elsewhere (CUDA) it is ``topk``.

    ``topk`` spends its time per entry of the row. The minima of ``k`` disjoint chunks of a row
    are ``k`` of its entries, so the ``k``-th smallest chunk minimum bounds the row's ``k``-th
    smallest entry from above; only the few entries under that bound (about 2k on 512-wide
    rows) go through ``topk``.

    Args:
        values: (..., M) float tensor, M >= k; entries may be -inf but not NaN or +inf.
        k: entries a row.
        chunk: entries a chunk; rows with fewer than ``k`` whole chunks use ``topk`` directly.

    Returns:
        (..., k) int64 indices into the last axis, in no particular order.
    """
    m = values.shape[-1]
    if m // chunk < k or values.device.type != "cpu":
        return values.topk(k, dim=-1, largest=False, sorted=False).indices
    rows = values.reshape(-1, m)
    minima = rows[:, : m // chunk * chunk].reshape(len(rows), -1, chunk).amin(-1)
    bound = minima.kthvalue(k, dim=-1, keepdim=True).values
    below = rows <= bound
    counts = below.sum(-1)
    row, col = below.nonzero(as_tuple=True)
    # Pack each row's candidates to the left of a (rows, most candidates) table.
    slot = torch.arange(len(row), device=rows.device) - (counts.cumsum(0) - counts)[row]
    width = int(counts.max())
    candidates = rows.new_full((len(rows), width), math.inf)
    candidates[row, slot] = rows[row, col]
    columns = torch.zeros((len(rows), width), dtype=torch.int64, device=rows.device)
    columns[row, slot] = col
    pick = candidates.topk(k, dim=-1, largest=False, sorted=False).indices
    return columns.gather(1, pick).reshape(*values.shape[:-1], k)


def gather_neighbours(x: Tensor, idx: Tensor) -> Tensor:
    """Features of each point's neighbours: x (B, N, C), idx (B, N, k) -> (B, N, k, C)."""
    b, n, c = x.shape
    offset = torch.arange(b, device=x.device).view(b, 1, 1) * n
    return x.reshape(b * n, c)[idx + offset]


class DenseEdgeConv(nn.Module):
    """A dense EdgeConv block (PU-GAN style): (B, N, C) -> (B, N, layers * growth + C).

    Neighbours are the ``k`` nearest in the block's input feature space, the point itself
    included. With the edge feature ``e_ij = [x_j - x_i, x_i]`` (2C channels):
    ``y1 = [f1(e_ij), x_i]``, ``y_l = [f_l(y_{l-1}), y_{l-1}]`` for the further layers, each
    ``f`` a 1x1 conv to ``growth`` channels (+ batch norm) + ReLU; the output is the max of the
    last ``y`` over the neighbours: ``[h_L, ..., h_1, x_i]``.

    The forward pass computes exactly this, but never builds the tiled ``x_i`` (B, N, k, C):
    a conv of a concatenation is the sum of convs of its parts, and the parts that depend on
    ``i`` only are computed once a point instead of once an edge.
    """

    def __init__(self, c_in: int, growth: int, layers: int, k: int, batch_norm: bool) -> None:
        super().__init__()
        self.k = k
        widths = [2 * c_in] + [c_in + i * growth for i in range(1, layers)]
        self.layers = nn.ModuleList(_Pointwise(w, growth, batch_norm) for w in widths)

    def forward(self, x: Tensor) -> Tensor:
        c = x.shape[-1]
        idx = knn_indices(x, self.k)
        first = self.layers[0].linear
        w_nb, w_centre = first.weight[:, :c], first.weight[:, c:]
        # W [x_j - x_i; x_i] = W_nb x_j + (W_centre - W_nb) x_i
        pre = gather_neighbours(x @ w_nb.T, idx)
        pre = pre + F.linear(x, w_centre - w_nb, first.bias).unsqueeze(2)
        hs = [self.layers[0].activate(pre)]
        for layer in self.layers[1:]:
            w = layer.linear.weight
            edges = hs[0] if len(hs) == 1 else torch.cat(hs[::-1], dim=-1)
            pre = edges @ w[:, :-c].T + F.linear(x, w[:, -c:], layer.linear.bias).unsqueeze(2)
            hs.append(layer.activate(pre))
        return torch.cat([max_over(h, 2) for h in reversed(hs)] + [x], dim=-1)


class FeatureExtractor(nn.Module):
    """The dense EdgeConv feature extractor: (B, N, 3) -> (B, N, ``config.point_channels``).

    ``l0`` = 1x1 conv 3 -> first_channels; ``l1 = [D(l0), l0]``; for every further block,
    ``l_i = [D(conv1x1(l_{i-1}) -> first_channels), l_{i-1}]``.
    """

    def __init__(self, config: PCNBVConfig) -> None:
        super().__init__()
        c0, bn = config.first_channels, config.batch_norm
        self.first = _Pointwise(3, c0, bn)
        self.blocks = nn.ModuleList(
            DenseEdgeConv(c0, config.growth, config.dense_layers, config.k, bn)
            for _ in range(config.blocks)
        )
        widths = [c0 + i * config.block_out_channels for i in range(1, config.blocks)]
        self.squeeze = nn.ModuleList(_Pointwise(w, c0, bn) for w in widths)

    def forward(self, points: Tensor) -> Tensor:
        # float32 even under autocast: its products are too narrow (12-60 channels) for
        # bfloat16 to pay, and its many small element-wise steps run slower in bfloat16.
        with _float32(points):
            features = self.first(points)
            features = torch.cat([self.blocks[0](features), features], dim=-1)
            for squeeze, block in zip(self.squeeze, self.blocks[1:], strict=True):
                features = torch.cat([block(squeeze(features)), features], dim=-1)
        return features


class SelfAttention(nn.Module):
    """SAGAN-style self-attention over points: (B, N, C) -> (B, N, C).

    ``out_i = gamma * sum_j softmax_j(q_i . k_j) v_j + x_i`` with 1x1 convs (with bias) for
    query, key (C -> ``channels``) and value (C -> C), no 1/sqrt(d) scaling, and a learnable
    scalar ``gamma`` that starts at 0 so the block starts as the identity.
    """

    def __init__(self, c_in: int, channels: int) -> None:
        super().__init__()
        self.query = nn.Linear(c_in, channels)
        self.key = nn.Linear(c_in, channels)
        self.value = nn.Linear(c_in, c_in)
        self.gamma = nn.Parameter(torch.zeros(()))

    def forward(self, x: Tensor) -> Tensor:
        # Written out rather than F.scaled_dot_product_attention: faster on CPU for these shapes.
        attention = torch.softmax(self.query(x) @ self.key(x).transpose(1, 2), dim=-1)
        return self.gamma * (attention @ self.value(x)) + x


class PCNBV(nn.Module):
    """The PC-NBV network (and PCNBV-sph with signature points as input).

    ``forward(points (B, N, 3), view_state (B, V)) -> (B, V)``: the predicted coverage gain of
    every view; unbounded (linear output). ``view_state`` is 1 (or True) for visited views.
    The output is invariant to the order of the points (in eval mode; in train mode batch norm
    statistics are order-invariant too, up to rounding).
    """

    def __init__(self, config: PCNBVConfig | None = None) -> None:
        super().__init__()
        self.config = config if config is not None else PCNBVConfig()
        cfg = self.config
        self.features = FeatureExtractor(cfg)
        self.attention = SelfAttention(cfg.concat_channels, cfg.attention_channels)
        widths = (cfg.concat_channels, *cfg.conv_channels)
        self.convs = nn.Sequential(
            *(
                _Pointwise(a, b, cfg.batch_norm)
                for a, b in zip(widths[:-1], widths[1:], strict=True)
            )
        )
        widths = (cfg.conv_channels[-1], *cfg.fc_channels)
        layers: list[nn.Module] = []
        for a, b in zip(widths[:-1], widths[1:], strict=True):
            layers += [nn.Linear(a, b), nn.ReLU()]
        layers.append(nn.Linear(widths[-1], cfg.n_views))
        self.head = nn.Sequential(*layers)

    def _check_inputs(self, points: Tensor, view_state: Tensor) -> None:
        v, k = self.config.n_views, self.config.k
        if points.ndim != 3 or points.shape[2] != 3:
            raise ValueError(f"points must have shape (B, N, 3), got {tuple(points.shape)}")
        dtype = self.attention.gamma.dtype
        if points.dtype != dtype:
            raise ValueError(
                f"points must be {dtype} like the network's weights, got {points.dtype}"
            )
        b, n = points.shape[:2]
        if view_state.shape != (b, v):
            raise ValueError(
                f"view_state must have shape (B, V) = ({b}, {v}), got {tuple(view_state.shape)}"
            )
        if n < k:
            raise ValueError(
                f"points must hold at least k = {k} points a sample, "
                f"got shape {tuple(points.shape)}"
            )
        if not torch.isfinite(points).all():
            raise ValueError("points must be finite, got NaN or inf")

    @staticmethod
    def normalize(points: Tensor) -> Tensor:
        """Centre every cloud at its centroid and scale it to max radius 1 (a cloud of one
        repeated point becomes all zeros): (B, N, 3) -> (B, N, 3)."""
        centred = points - points.mean(dim=1, keepdim=True)
        radius = centred.norm(dim=-1).amax(dim=1).view(-1, 1, 1)
        return centred / torch.where(radius > 0, radius, torch.ones_like(radius))

    def forward(self, points: Tensor, view_state: Tensor) -> Tensor:
        """Predicted gain of every view.

        Args:
            points: (B, N, 3) in the network's dtype (float32 unless converted), N >= ``config.k``.
            view_state: (B, V) bool or float, 1 = visited.

        Returns:
            (B, V) float, same dtype as ``points`` (also under bfloat16 :func:`autocast`).
        """
        self._check_inputs(points, view_state)
        if self.config.normalize_input:
            points = self.normalize(points)
        per_point = self.features(points)
        kind = per_point.device.type
        if torch.is_autocast_enabled(kind):
            # Cast once here: autocast would cast the concatenation again for every layer of
            # the attention and for the first 1x1 conv.
            per_point = per_point.to(torch.get_autocast_dtype(kind))
        n = per_point.shape[1]
        tiled_global = max_over(per_point, 1, keepdim=True).expand(-1, n, -1)
        tiled_state = view_state.to(per_point.dtype).unsqueeze(1).expand(-1, n, -1)
        x = torch.cat([per_point, tiled_global, tiled_state], dim=-1)
        x = max_over(self.convs(self.attention(x)), 1)
        with _float32(x):
            return self.head(x.to(points.dtype))


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
        if isinstance(module, _Pointwise) and module.norm is not None:
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


def count_parameters(model: nn.Module) -> int:
    """Number of trainable scalars (parameters with ``requires_grad``)."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


class CheckpointError(ValueError):
    """A checkpoint file is missing, unreadable, or does not fit the network it should hold."""


def _check_plain(value: Any, where: str) -> None:
    """Raise ``TypeError`` unless ``value`` is built of types that ``torch.load`` with
    ``weights_only=True`` reads back: dict with str keys, list, tuple, str, int, float, bool,
    None, tensors."""
    if isinstance(value, Mapping):
        for key, item in value.items():
            if not isinstance(key, str):
                raise TypeError(f"checkpoint extra{where}: keys must be str, got {key!r}")
            _check_plain(item, f"{where}[{key!r}]")
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _check_plain(item, f"{where}[{i}]")
    elif not (value is None or isinstance(value, str | int | float | bool | Tensor)):
        raise TypeError(
            f"checkpoint extra{where} is a {type(value).__name__}; allowed: dict, list, tuple, "
            "str, int, float, bool, None, torch.Tensor (convert numpy values and paths first)"
        )


def save_checkpoint(path: str | os.PathLike[str], model: PCNBV, extra: Mapping[str, Any]) -> None:
    """Write the weights, the model config and ``extra`` (training config, dataset identity,
    epoch, metrics, ...) to ``path`` atomically: a temporary file in the same folder, renamed
    over ``path`` once complete. Creates missing parent folders.

    Raises:
        TypeError: ``extra`` holds a value :func:`load_checkpoint` could not read back safely.
    """
    _check_plain(dict(extra), "")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": CHECKPOINT_FORMAT,
        "version": CHECKPOINT_VERSION,
        "config": model.config.to_dict(),
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "extra": dict(extra),
    }
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            torch.save(payload, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load_checkpoint(
    path: str | os.PathLike[str],
    map_location: str | torch.device = "cpu",
    n_views: int | None = None,
) -> tuple[PCNBV, dict[str, Any]]:
    """Read a checkpoint written by :func:`save_checkpoint`.

    Args:
        path: the checkpoint file.
        map_location: device of the returned model.
        n_views: if given, the number of views the network must have.

    Returns:
        ``(model, extra)``: the network in eval mode, and the ``extra`` dict it was saved with.

    Raises:
        CheckpointError: (naming the file) it is missing, not a torch file, not a PCNBV
            checkpoint, its config is invalid, its weights do not fit its config, or its
            number of views differs from ``n_views``.
    """
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist or is not a file")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as e:
        raise CheckpointError(f"checkpoint {path} is not a readable torch file: {e}") from e
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"checkpoint {path} is not a PCNBV checkpoint (no format tag)")
    if payload.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(
            f"checkpoint {path} has version {payload.get('version')!r}; "
            f"this code reads version {CHECKPOINT_VERSION}"
        )
    missing = [k for k in ("config", "state_dict", "extra") if not isinstance(payload.get(k), dict)]
    if missing:
        raise CheckpointError(f"checkpoint {path} lacks the dicts {missing}")
    try:
        config = PCNBVConfig.from_dict(payload["config"])
    except (TypeError, ValueError) as e:
        raise CheckpointError(f"checkpoint {path} has an invalid config: {e}") from e
    if n_views is not None and config.n_views != n_views:
        raise CheckpointError(
            f"checkpoint {path} is a network for {config.n_views} views, expected {n_views}"
        )
    model = PCNBV(config)
    try:
        model.load_state_dict(payload["state_dict"], strict=True)
    except (RuntimeError, TypeError, AttributeError) as e:
        reason = " ".join(str(e).split())  # torch's message spans lines
        raise CheckpointError(f"checkpoint {path} weights do not fit its config: {reason}") from e
    return model.to(map_location).eval(), dict(payload["extra"])
