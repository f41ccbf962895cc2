"""A point-cloud completion network: the captured cloud in, points on the whole surface out.

Why this architecture: PCN's encoder (two shared-MLP stages around a max-pool) with a
coarse fully connected head and a folding refinement, made narrower, so that it trains on two CPU
cores. Every layer is a plain matrix product (no neighbour search, no CUDA-only sampling or
Chamfer kernels, which PoinTr, SnowflakeNet and GRNet need as released), and its cost is linear in
the number of points.

- encoder: shared MLP ``3 -> e1[0] -> e1[1]`` per point, max-pool, the pooled feature tiled
  beside each point's, shared MLP ``2 e1[1] -> e2[0] -> e2[1]``, max-pool: a global feature;
- coarse head: fully connected ``e2[1] -> coarse_hidden -> 3 n_coarse``: the coarse cloud;
- folding: each coarse point is copied ``fold ** 2`` times, each copy with a point of a
  ``fold x fold`` grid of side ``2 fold_scale``; an MLP of [global feature, grid point, coarse
  point] gives an offset from the coarse point: the fine cloud, ``n_coarse fold ** 2`` points.

Clouds are in the dataset's normalised frame (the object within the sphere of radius 0.5 about
the origin): the network sees where the captured points lie, and predicts in the same frame.

The loss is Chamfer's, on the coarse and the fine clouds (:func:`chamfer_l1`): "CD-L1", the mean
of the two sides' mean Euclidean nearest distances (PCN, PoinTr), computed in plain torch (the
neighbours found by a k-d tree, the distances and their gradients by torch).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
from scipy.spatial import cKDTree
from torch import Tensor, nn


@dataclass(frozen=True)
class CompletionConfig:
    """The shape of a :class:`CompletionNet`.

    Attributes:
        n_input: points of the input cloud (the captured cloud is farthest-point sampled to it).
        encoder1: widths of the first shared MLP.
        encoder2: widths of the second shared MLP; the last is the global feature's size.
        coarse_hidden: widths of the coarse head's hidden layers.
        n_coarse: points of the coarse cloud.
        fold: side of the folding grid; the fine cloud has ``n_coarse * fold ** 2`` points.
        fold_scale: half the side of the folding grid, in the cloud's units.
        fold_hidden: widths of the folding MLP's hidden layers.
    """

    n_input: int = 512
    encoder1: tuple[int, int] = (64, 128)
    encoder2: tuple[int, int] = (256, 512)
    coarse_hidden: tuple[int, ...] = (1024,)
    n_coarse: int = 512
    fold: int = 2
    fold_scale: float = 0.02
    fold_hidden: tuple[int, ...] = (128, 128)

    @property
    def n_fine(self) -> int:
        """Points of the fine (output) cloud."""
        return self.n_coarse * self.fold**2

    def to_dict(self) -> dict:
        """Plain JSON types, for a checkpoint."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict) -> CompletionConfig:
        """The config of :meth:`to_dict`'s output.

        Raises:
            ValueError: an unknown key (the message names it).
        """
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"unknown completion config keys {unknown}; allowed: {sorted(known)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


def _shared_mlp(widths: list[int]) -> nn.Sequential:
    """1x1 convolutions ``widths[0] -> ... -> widths[-1]`` with ReLU between (not after the
    last)."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(widths[:-1], widths[1:], strict=True)):
        layers.append(nn.Conv1d(a, b, 1))
        if i < len(widths) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


def _mlp(widths: list[int]) -> nn.Sequential:
    """Linear layers ``widths[0] -> ... -> widths[-1]`` with ReLU between."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(widths[:-1], widths[1:], strict=True)):
        layers.append(nn.Linear(a, b))
        if i < len(widths) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class CompletionNet(nn.Module):
    """See the module docstring. ``forward(points)``: (B, n_input, 3) -> (coarse (B, n_coarse,
    3), fine (B, n_fine, 3)), float32, the input's frame and units."""

    def __init__(self, config: CompletionConfig | None = None) -> None:
        super().__init__()
        self.config = c = config or CompletionConfig()
        e1, e2 = c.encoder1, c.encoder2
        self.first = _shared_mlp([3, *e1])
        self.second = _shared_mlp([2 * e1[-1], *e2])
        self.coarse = _mlp([e2[-1], *c.coarse_hidden, 3 * c.n_coarse])
        hidden = c.fold_hidden[0]
        # The folding MLP's first layer on [feature, grid, coarse point] as three products
        # summed: the feature's once a cloud, the grid's once, the coarse point's once a point.
        self.fold_feature = nn.Linear(e2[-1], hidden)
        self.fold_grid = nn.Linear(2, hidden, bias=False)
        self.fold_point = nn.Linear(3, hidden, bias=False)
        self.fold_rest = _mlp([*c.fold_hidden, 3])
        side = torch.linspace(-c.fold_scale, c.fold_scale, c.fold)
        grid = torch.stack(torch.meshgrid(side, side, indexing="ij"), dim=-1).reshape(-1, 2)
        self.register_buffer("grid", grid, persistent=False)

    def encode(self, points: Tensor) -> Tensor:
        """(B, N, 3) -> (B, encoder2[-1]) global feature."""
        x = points.transpose(1, 2)
        f = self.first(x)
        pooled = f.max(dim=2, keepdim=True).values.expand_as(f)
        return self.second(torch.cat([f, pooled], dim=1)).max(dim=2).values

    def forward(self, points: Tensor) -> tuple[Tensor, Tensor]:
        c = self.config
        feature = self.encode(points)
        coarse = self.coarse(feature).reshape(-1, c.n_coarse, 3)
        h = (
            self.fold_feature(feature)[:, None, None, :]
            + self.fold_grid(self.grid)[None, None, :, :]
            + self.fold_point(coarse)[:, :, None, :]
        )
        offsets = self.fold_rest(torch.relu(h))
        fine = (coarse[:, :, None, :] + offsets).reshape(-1, c.n_fine, 3)
        return coarse.float(), fine.float()


def nearest_indices(a: Tensor, b: Tensor) -> Tensor:
    """(B, N) int64 index of each point of ``a`` (B, N, 3)'s nearest point of ``b`` (B, M, 3),
    by a k-d tree per cloud (scipy): no gradient flows through a choice of neighbour, and the
    tree is 5-10x faster than the B x N x M distance matrix on a CPU."""
    a_np = a.detach().float().cpu().numpy()
    b_np = b.detach().float().cpu().numpy()
    rows = [cKDTree(bb).query(aa)[1] for aa, bb in zip(a_np, b_np, strict=True)]
    return torch.from_numpy(np.stack(rows).astype(np.int64)).to(a.device)


def nearest_distances(a: Tensor, b: Tensor) -> Tensor:
    """(B, N) Euclidean distance from each point of ``a`` (B, N, 3) to its nearest point of ``b``
    (B, M, 3), differentiable in both clouds (:func:`nearest_indices` picks the neighbours).

    Squared distances are clamped at 1e-12 before the square root, so that the gradient of a
    point on top of another stays finite."""
    index = nearest_indices(a, b)
    nearest = torch.gather(b.float(), 1, index[..., None].expand(-1, -1, 3))
    return ((a.float() - nearest) ** 2).sum(-1).clamp_min(1e-12).sqrt()


def chamfer_l1(a: Tensor, b: Tensor) -> Tensor:
    """(B,) CD-L1 between clouds ``a`` (B, N, 3) and ``b`` (B, M, 3): the mean of the two sides'
    mean Euclidean nearest distance, ``(mean_a d(a, b) + mean_b d(b, a)) / 2``, cloud units."""
    return (nearest_distances(a, b).mean(1) + nearest_distances(b, a).mean(1)) / 2


def completion_macs(config: CompletionConfig) -> int:
    """Multiply-adds of the matrix products of one forward pass of one sample (biases,
    ReLU and max-pools left out: a few percent)."""
    c = config
    widths1, widths2 = [3, *c.encoder1], [2 * c.encoder1[-1], *c.encoder2]
    per_point = sum(p * q for p, q in zip(widths1[:-1], widths1[1:], strict=True))
    per_point += sum(p * q for p, q in zip(widths2[:-1], widths2[1:], strict=True))
    head = [c.encoder2[-1], *c.coarse_hidden, 3 * c.n_coarse]
    macs = c.n_input * per_point + sum(p * q for p, q in zip(head[:-1], head[1:], strict=True))
    hidden = c.fold_hidden[0]
    macs += c.encoder2[-1] * hidden + c.fold**2 * 2 * hidden + c.n_coarse * 3 * hidden
    rest = [*c.fold_hidden, 3]
    macs += c.n_fine * sum(p * q for p, q in zip(rest[:-1], rest[1:], strict=True))
    return macs


def completion_flops(config: CompletionConfig) -> int:
    """FLOPs (2 a multiply-add) of one forward pass of one sample (:func:`completion_macs`)."""
    return 2 * completion_macs(config)


def parameter_count(model: nn.Module) -> int:
    """Trainable parameters of ``model``."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
