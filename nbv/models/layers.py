"""The layers of :class:`~nbv.models.pcnbv.PCNBV`: 1x1 convs, dense EdgeConv blocks, the
feature extractor and self-attention.

Features are laid out points-last-but-one, ``(B, N, C)``, so every "1x1 conv" is a single matrix
product (``nn.Linear``) over the channel axis.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from nbv.models.config import PCNBVConfig
from nbv.models.neighbours import gather_neighbours, knn_indices
from nbv.models.precision import in_float32


class Pointwise(nn.Module):
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


def max_over_neighbours(x: Tensor) -> Tensor:
    """The max over the neighbour axis of edge features: (B, N, k, C) -> (B, N, C), the values
    of ``max_over(x, 2)``.

    Without autograd the axis is halved by element-wise maxima (``log2 k`` of them): torch's
    reduction runs its few (16) entries with the narrow channel axis (12) innermost at about a
    sixth of the speed (0.76 ms against 0.13 for 4 x 512 points, one thread).
    """
    if x.requires_grad and torch.is_grad_enabled():
        return max_over(x, 2)
    while x.shape[2] > 1:
        half = x.shape[2] // 2
        pairs = torch.maximum(x[:, :, :half], x[:, :, half : 2 * half])
        if x.shape[2] % 2:
            torch.maximum(pairs[:, :, :1], x[:, :, 2 * half :], out=pairs[:, :, :1])
        x = pairs
    return x[:, :, 0]


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
        self.layers = nn.ModuleList(Pointwise(w, growth, batch_norm) for w in widths)

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
        return torch.cat([max_over_neighbours(h) for h in reversed(hs)] + [x], dim=-1)


class FeatureExtractor(nn.Module):
    """The dense EdgeConv feature extractor: (B, N, 3) -> (B, N, ``config.point_channels``).

    ``l0`` = 1x1 conv 3 -> first_channels; ``l1 = [D(l0), l0]``; for every further block,
    ``l_i = [D(conv1x1(l_{i-1}) -> first_channels), l_{i-1}]``.
    """

    def __init__(self, config: PCNBVConfig) -> None:
        super().__init__()
        c0, bn = config.first_channels, config.batch_norm
        self.first = Pointwise(3, c0, bn)
        self.blocks = nn.ModuleList(
            DenseEdgeConv(c0, config.growth, config.dense_layers, config.k, bn)
            for _ in range(config.blocks)
        )
        widths = [c0 + i * config.block_out_channels for i in range(1, config.blocks)]
        self.squeeze = nn.ModuleList(Pointwise(w, c0, bn) for w in widths)

    def forward(self, points: Tensor) -> Tensor:
        # float32 even under autocast: its products are too narrow (12-60 channels) for
        # bfloat16 to pay, and its many small element-wise steps run slower in bfloat16.
        with in_float32(points):
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
