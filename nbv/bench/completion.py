"""Benchmark rows of the completion network and the planners that use it (``make bench``).

- A decision of ``completion_gain`` and of ``completion_hull_sco`` on a 33-view candidate set
  after three captured views (2,048 points each, as the dataset stores them), on one torch
  thread: the network's forward pass, then the view contribution or the set cover. The
  reference is the same decision by [15]'s rule as the seed paper's authors ran it
  (``completion_gain_authors``: hidden-point removal from each candidate). Target: 50 ms.
- A training step of the completion network (batch 32, the shipped configuration, training's
  precision) against its FLOP floor (:func:`nbv.bench.floor.floor_rate` on the same threads; a
  step counts three forward passes), on seeded random clouds: the row times the network and the
  optimizer, not the loading of samples.
"""

from __future__ import annotations

import numpy as np

from nbv.bench.timing import best_time, torch_threads
from nbv.geometry.camera import Intrinsics
from nbv.geometry.scores import DEFAULT_EPS
from nbv.policies.episode import EPISODE_VIEWS, captured_state
from nbv.policies.method import MethodContext
from nbv.policies.registry import (
    COMPLETION_GAIN,
    COMPLETION_GAIN_AUTHORS,
    COMPLETION_HULL_SCO,
    METHODS,
)
from nbv.scan.shipped import ShippedCompletion
from nbv.setcover.settings import SetCoverSettings
from nbv.utils.seeding import named_rng

#: The decision target of issue 53, seconds on one core.
DECISION_TARGET = 0.050
#: Captured views before the timed decision.
CAPTURED = (1, 15, 27)
#: Samples of a timed training step (``python -m train.completion``'s default batch).
TRAIN_BATCH = 32


def decision_rows(
    stored: list[np.ndarray], poses: np.ndarray, intrinsics: Intrinsics
) -> list[dict]:
    """One decision of each completion planner after the views :data:`CAPTURED`, one thread."""
    parts = [stored[v] if v in CAPTURED else np.zeros((0, 3)) for v in range(len(poses))]
    state = captured_state(poses, parts, list(CAPTURED))
    completion = ShippedCompletion()
    completion.completer()  # loaded once, as an evaluation loads it
    ctx = MethodContext({}, SetCoverSettings(), intrinsics, DEFAULT_EPS, EPISODE_VIEWS,
                        completion=completion)  # fmt: skip

    def decide(name: str):
        return METHODS[name].build(ctx, named_rng(0, "plan", name))(state)

    rows = []
    with torch_threads(1):
        reference = best_time(lambda: decide(COMPLETION_GAIN_AUTHORS.name), repeat=3, budget=20)
        for method in (COMPLETION_GAIN, COMPLETION_HULL_SCO):
            ours = best_time(lambda m=method: decide(m.name), repeat=5, budget=10)
            rows.append(dict(
                name=f"{method.name} decision, 33 candidates, {len(CAPTURED)} captured views, "
                "1 thread",
                ours=ours, reference=reference, ratio=reference / ours, target=DECISION_TARGET,
                note="network + planner vs the same network + [15]'s rule (hidden-point "
                "removal from each candidate)",
            ))  # fmt: skip
    return rows


def training_row(threads: int | None = None, precision: str = "auto", seed: int = 0) -> dict:
    """A training step of the shipped configuration against its FLOP floor."""
    import torch

    from nbv.bench.floor import PRODUCT_NAMES, floor_rate
    from nbv.models.completion import CompletionNet, chamfer_l1, completion_flops
    from nbv.models.precision import autocast, flush_denormals, resolve_precision

    resolved = resolve_precision(precision)
    config = ShippedCompletion().completer().model.config
    gen = torch.Generator().manual_seed(seed)
    x = torch.rand(TRAIN_BATCH, config.n_input, 3, generator=gen) - 0.5
    gt = torch.rand(TRAIN_BATCH, 2048, 3, generator=gen) - 0.5
    torch.manual_seed(seed)
    net = CompletionNet(config).train()
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)

    def step() -> None:
        opt.zero_grad()
        with autocast(resolved):
            coarse, fine = net(x)
        (chamfer_l1(coarse, gt) + chamfer_l1(fine, gt)).mean().backward()
        opt.step()

    with flush_denormals(), torch_threads(threads):
        n_threads = torch.get_num_threads()
        step()
        seconds = best_time(step, repeat=3, budget=30)
    rate = floor_rate(threads, resolved)
    forward = completion_flops(config)
    floor = TRAIN_BATCH * 3 * forward / rate.flops
    kind = "float32" if resolved == "fp32" else f"{PRODUCT_NAMES[resolved]} autocast"
    return dict(
        name=f"completion training step, batch {TRAIN_BATCH} x {config.n_input} points, {kind}",
        ours=seconds, reference=floor, ratio=floor / seconds, target=None,
        samples_per_s=TRAIN_BATCH / seconds, floor_samples_per_s=TRAIN_BATCH / floor,
        forward_flops=float(forward), threads=n_threads, precision=resolved,
        note=f"{TRAIN_BATCH / seconds:.1f} samples/s on {n_threads} threads vs the FLOP floor of "
        f"{TRAIN_BATCH / floor:.1f}: {TRAIN_BATCH} x 3 x {forward / 1e9:.3g} GFLOP / "
        f"{rate.describe()}; the Chamfer loss's neighbour search is not counted",
    )  # fmt: skip


def completion_rows(
    stored: list[np.ndarray], poses: np.ndarray, intrinsics: Intrinsics
) -> list[dict]:
    """Every row of this module."""
    return [*decision_rows(stored, poses, intrinsics), training_row()]
