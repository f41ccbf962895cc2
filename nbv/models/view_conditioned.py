"""A viewspace-conditioned next-best-view network (beyond the paper), and its checkpoints.

PCNBV has one output per index of a fixed viewspace, so a viewspace in another order or with
other directions means nothing to it. This network scores each candidate *from its direction*:

* a point MLP embeds every point of the accumulated cloud (world frame, object at the origin);
  its max over points is the cloud's global feature;
* for a candidate direction ``d``, each point's embedding is joined with its depth along ``d``
  (``p . d``) and its squared distance from the axis through ``d``, passed through a second MLP
  and max-pooled: what the cloud looks like from ``d``;
* the visited directions enter through the candidate's largest and mean cosine to them and the
  mean of a small MLP of them;
* with ``map_features > 0`` (the ``vcnbv_map`` variant), each candidate's numbers of what its
  rays would see on an occupancy map of the captured views
  (:func:`nbv.infogain.view_features.view_features`) join its features;
* a head maps the joined features of each candidate to its score.

Any number of candidates in any order: inputs ``(B, N, 3)`` points, ``(B, V, 3)`` unit
directions and a ``(B, V)`` view state; output ``(B, V)`` scores (the best view is the argmax
over the unvisited ones).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import torch
from torch import Tensor, nn

from nbv.models.checkpoints import CheckpointError, read_payload, write_payload

#: The file-format tag of this network's checkpoints.
CONDITIONED_FORMAT = "nbv.net.ViewConditioned"
CONDITIONED_VERSION = 1


@dataclass(frozen=True)
class ConditionedConfig:
    """Sizes of a :class:`ViewConditionedNet` (widths of its MLPs)."""

    point_channels: tuple[int, ...] = (64, 128)
    view_channels: tuple[int, ...] = (32, 32)
    visited_channels: int = 32
    head_channels: tuple[int, ...] = (128, 64)
    #: Map features per candidate the head also reads (0: the cloud and directions only).
    map_features: int = 0

    def __post_init__(self) -> None:
        for key in ("point_channels", "view_channels", "head_channels"):
            widths = getattr(self, key)
            if not widths or any(int(w) != w or w < 1 for w in widths):
                raise ValueError(f"net.{key}={list(widths)}: must be a non-empty list of "
                                 f"integers >= 1")  # fmt: skip
        if self.visited_channels < 1 or self.map_features < 0:
            raise ValueError(
                f"net.visited_channels={self.visited_channels}, map_features="
                f"{self.map_features}: must be >= 1 and >= 0"
            )

    def to_dict(self) -> dict[str, Any]:
        """Plain values for a checkpoint."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> ConditionedConfig:
        """Inverse of :meth:`to_dict` (unknown keys raise ``TypeError``)."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


def _mlp(sizes: list[int], last_activation: bool = True) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
        layers.append(nn.Linear(a, b))
        if last_activation or i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class ViewConditionedNet(nn.Module):
    """See the module docstring."""

    def __init__(self, config: ConditionedConfig | None = None) -> None:
        super().__init__()
        self.config = c = config or ConditionedConfig()
        self.points = _mlp([3, *c.point_channels])
        width = c.point_channels[-1]
        # The first layer of the per-candidate MLP, split: the points' part once per point, the
        # candidate's (depth, axis distance) part per pair; the same map as one layer on both.
        self.view_points = nn.Linear(width, c.view_channels[0], bias=False)
        self.view_axis = nn.Linear(2, c.view_channels[0])
        self.view = _mlp(list(c.view_channels))
        self.visited = _mlp([3, c.visited_channels])
        joined = width + c.view_channels[-1] + 3 + 2 + c.visited_channels + c.map_features
        self.head = _mlp([joined, *c.head_channels, 1], last_activation=False)

    def forward(
        self, points: Tensor, directions: Tensor, view_state: Tensor, features: Tensor | None = None
    ) -> Tensor:
        """Scores of every candidate.

        Args:
            points: (B, N, 3) float clouds, world units (the object about the origin).
            directions: (B, V, 3) float unit candidate directions (camera positions over their
                norm).
            view_state: (B, V) 0/1, 1 = visited; a sample needs at least one visited view.
            features: (B, V, config.map_features) float map features of the candidates (any
                value for visited ones); required when ``config.map_features > 0``, else None.

        Returns:
            (B, V) float scores.
        """
        want = self.config.map_features
        got = None if features is None else tuple(features.shape)
        if (want == 0) != (features is None) or (want and got != (*view_state.shape, want)):
            raise ValueError(
                f"this network reads {want} map features per candidate; got features of shape "
                f"{got} for a view state of shape {tuple(view_state.shape)}"
            )
        feats = self.points(points)  # (B, N, W)
        global_ = feats.amax(dim=1)  # (B, W)
        depth = torch.einsum("bnc,bvc->bvn", points, directions)  # (B, V, N)
        axis = (points**2).sum(-1)[:, None, :] - depth**2
        b, v, n = depth.shape
        first = self.view_points(feats)[:, None] + self.view_axis(torch.stack([depth, axis], -1))
        seen_from = self.view(torch.relu(first)).amax(dim=2)  # (B, V, C)
        visited = view_state.float()
        count = visited.sum(dim=1, keepdim=True).clamp_min(1.0)
        cosine = torch.einsum("bvc,bwc->bvw", directions, directions)
        nearest = cosine.masked_fill(visited[:, None, :] < 0.5, -2.0).amax(dim=2)
        mean_cos = (cosine * visited[:, None, :]).sum(dim=2) / count
        pooled = (self.visited(directions) * visited[..., None]).sum(dim=1) / count  # (B, D)
        joined = torch.cat(
            [
                global_[:, None].expand(b, v, global_.shape[-1]),
                seen_from,
                directions,
                nearest[..., None],
                mean_cos[..., None],
                pooled[:, None].expand(b, v, pooled.shape[-1]),
                *([] if features is None else [features.to(points.dtype)]),
            ],
            dim=-1,
        )
        return self.head(joined)[..., 0]


def save_conditioned(
    path: str | os.PathLike[str], model: ViewConditionedNet, extra: dict[str, Any]
) -> None:
    """Write weights, config and ``extra`` atomically (the layout of
    :func:`nbv.models.checkpoints.save_checkpoint`, another format tag)."""
    write_payload(path, CONDITIONED_FORMAT, CONDITIONED_VERSION, model, extra)


def load_conditioned(path: str | os.PathLike[str]) -> tuple[ViewConditionedNet, dict[str, Any]]:
    """Read a checkpoint of :func:`save_conditioned`: ``(model in eval mode, extra)``.

    Raises:
        CheckpointError: (naming the file) missing, unreadable, another format or version, or
            weights that do not fit the config.
    """
    path = Path(path)
    payload = read_payload(
        path, CONDITIONED_FORMAT, CONDITIONED_VERSION, "view-conditioned network"
    )
    try:
        model = ViewConditionedNet(ConditionedConfig.from_dict(payload["config"]))
        # Shipped weights are bfloat16; the network runs in float32.
        model.load_state_dict({k: v.float() for k, v in payload["state_dict"].items()}, strict=True)
    except (TypeError, ValueError, RuntimeError) as e:
        reason = " ".join(str(e).split())
        raise CheckpointError(f"checkpoint {path} does not fit its config: {reason}") from e
    return model.eval(), dict(payload["extra"])
