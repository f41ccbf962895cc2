"""PCNBV: the point-cloud next-best-view network.

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
single matrix product (``nn.Linear``) over the channel axis. Sizes: :mod:`nbv.models.config`;
precision: :mod:`nbv.models.precision`.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from nbv.models.config import PCNBVConfig
from nbv.models.layers import FeatureExtractor, Pointwise, SelfAttention, max_over
from nbv.models.precision import in_float32


def check_inputs(
    config: PCNBVConfig, dtype: torch.dtype, points: Tensor, view_state: Tensor
) -> None:
    """Refuse inputs a PCNBV of ``config`` with weights of ``dtype`` cannot read: points not
    (B, N >= k, 3) of that dtype or not finite, a view state not (B, V).

    Raises:
        ValueError: naming the input, its shape or dtype, and what is allowed.
    """
    v, k = config.n_views, config.k
    if points.ndim != 3 or points.shape[2] != 3:
        raise ValueError(f"points must have shape (B, N, 3), got {tuple(points.shape)}")
    if points.dtype != dtype:
        raise ValueError(f"points must be {dtype} like the network's weights, got {points.dtype}")
    b, n = points.shape[:2]
    if view_state.shape != (b, v):
        raise ValueError(
            f"view_state must have shape (B, V) = ({b}, {v}), got {tuple(view_state.shape)}"
        )
    if n < k:
        raise ValueError(
            f"points must hold at least k = {k} points a sample, got shape {tuple(points.shape)}"
        )
    if not torch.isfinite(points).all():
        raise ValueError("points must be finite, got NaN or inf")


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
            *(Pointwise(a, b, cfg.batch_norm) for a, b in zip(widths[:-1], widths[1:], strict=True))
        )
        widths = (cfg.conv_channels[-1], *cfg.fc_channels)
        layers: list[nn.Module] = []
        for a, b in zip(widths[:-1], widths[1:], strict=True):
            layers += [nn.Linear(a, b), nn.ReLU()]
        layers.append(nn.Linear(widths[-1], cfg.n_views))
        self.head = nn.Sequential(*layers)

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
        check_inputs(self.config, self.attention.gamma.dtype, points, view_state)
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
        with in_float32(x):
            return self.head(x.to(points.dtype))


def count_parameters(model: nn.Module) -> int:
    """Number of trainable scalars (parameters with ``requires_grad``)."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
