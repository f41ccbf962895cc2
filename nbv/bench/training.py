"""Time a training step of PCNBV and PCNBV-sph beside its FLOP floor (rows of ``make bench``).

A step is what ``python -m train`` runs for each batch: zero the gradients, a forward pass under
the training precision's autocast (:func:`nbv.models.precision.autocast`; ``auto``, training's
default: bfloat16 on a CPU that runs it natively, else float32), the loss, a backward pass and an
Adam step, with subnormals flushed as training flushes them
(:func:`nbv.models.precision.flush_denormals`). The benchmark is an entry point beside ``train``
and may not import it (the layers contract of ``pyproject.toml``), so its loss is a squared error
summed over the V outputs and averaged over the batch, on seeded random targets, without an L2
penalty: any of training's losses is a few element-wise operations on a (batch, V) array, next
to the network's products. The batch is built once: the rows time the network and the
optimizer, not the loading of samples (``metrics.csv``'s ``load_fraction`` gives that).

The floor of a step is ``batch x 3 x`` the FLOPs of a forward pass as written
(:func:`nbv.bench.floor.training_flops`) over :func:`nbv.bench.floor.floor_rate` on the same
threads.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from nbv.bench.network import input_points, load_network
from nbv.bench.timing import best_time, torch_threads

#: Samples a training step of the rows holds (``python -m train``'s default ``batch_size``).
TRAIN_BATCH = 32
#: Adam's learning rate in the rows (the authors' schedule's first; its value costs nothing).
TRAIN_LR = 1e-4


def random_batch(n_points: int, n_views: int, batch: int = TRAIN_BATCH, seed: int = 0) -> tuple:
    """A seeded training batch of tensors: clouds (batch, n_points, 3) float32 of standard
    normal coordinates, view states (batch, n_views) float32 of 0 and 1 (a view visited with
    probability 0.2), and targets (batch, n_views) float32, uniform in [0, 1) on the unvisited
    views and 0 on the visited."""
    import torch

    rng = np.random.default_rng(seed)
    points = rng.standard_normal((batch, n_points, 3), dtype=np.float32)
    state = (rng.random((batch, n_views)) < 0.2).astype(np.float32)
    target = (rng.random((batch, n_views)) * (1 - state)).astype(np.float32)
    return torch.from_numpy(points), torch.from_numpy(state), torch.from_numpy(target)


def training_step(model, optimizer, batch: tuple, precision: str = "auto") -> float:
    """One step on ``batch`` (:func:`random_batch`'s clouds, view states and targets): zero the
    gradients, forward under :func:`nbv.models.precision.autocast` of ``precision``, the squared
    error summed over the views and averaged over the batch, backward, ``optimizer.step()``.
    Returns the loss before the step."""
    from nbv.models.precision import autocast

    points, state, target = batch
    optimizer.zero_grad()
    with autocast(precision):
        pred = model(points, state)
    loss = ((pred.float() - target) ** 2).sum(dim=1).mean()
    loss.backward()
    optimizer.step()
    return loss.item()


def step_seconds(
    model,
    n_points: int,
    batch: int = TRAIN_BATCH,
    precision: str = "auto",
    threads: int | None = None,
    repeat: int = 3,
    budget: float = 30.0,
    seed: int = 0,
) -> float:
    """Best wall time in seconds of a :func:`training_step` of ``model`` (a
    :class:`~nbv.models.pcnbv.PCNBV`, put in training mode and trained by the steps) with Adam on
    a :func:`random_batch` of ``batch`` samples of ``n_points`` points, over up to ``repeat``
    steps (fewer once ``budget`` seconds are spent) after one warm-up step (it allocates Adam's
    state and picks kernels), on ``threads`` torch threads (None: the process's), subnormals
    flushed."""
    import torch

    from nbv.models.precision import flush_denormals

    data = random_batch(n_points, model.config.n_views, batch, seed)
    optimizer = torch.optim.Adam(model.parameters(), lr=TRAIN_LR)
    model.train()
    with flush_denormals(), torch_threads(threads):
        training_step(model, optimizer, data, precision)
        return best_time(lambda: training_step(model, optimizer, data, precision), repeat, budget)


def training_rows(
    networks: Sequence[tuple[str, Path]],
    n_views: int = 33,
    batch: int = TRAIN_BATCH,
    precision: str = "auto",
    threads: int | None = None,
    repeat: int = 3,
) -> list[dict]:
    """The training rows of ``make bench``, one for each ``(name, checkpoint)`` of
    ``networks``: a training step of the checkpoint's network (:func:`step_seconds`; the points
    of its input, :func:`nbv.bench.network.input_points`) against the step's FLOP floor on the
    same threads.

    Rows: dicts of name, ours (seconds a step), reference (the floor's seconds a step), ratio
    (reference / ours: the share of the floor's speed reached), target (None), note; and
    ``samples_per_s`` (batch / ours), ``floor`` (= reference), ``floor_samples_per_s``
    (batch / floor), ``floor_of_clock`` (seconds at the clock formula's peak alone),
    ``forward_flops`` and ``train_flops`` (of one sample), ``batch``, ``points``, ``threads``,
    ``precision`` (resolved: ``fp32`` or ``bf16``) and ``matmul_gflops`` (plus
    ``matmul_bf16_gflops`` under bfloat16).
    """
    import torch

    from nbv.bench.floor import PRODUCT_NAMES, floor_rate, pcnbv_flops, training_flops
    from nbv.models.precision import resolve_precision
    from nbv.policies.network import NetworkPolicy

    resolved = resolve_precision(precision)
    rate = floor_rate(threads, resolved)
    with torch_threads(threads):
        n_threads = torch.get_num_threads()
    kind = "float32" if resolved == "fp32" else f"{PRODUCT_NAMES[resolved]} autocast"
    rows = []
    for name, checkpoint in networks:
        points = input_points(NetworkPolicy.from_checkpoint(checkpoint, n_views, "fp32"))
        net = load_network(checkpoint, n_views)
        seconds = step_seconds(net, points, batch, resolved, threads, repeat)
        forward = pcnbv_flops(net.config, points)
        per_sample = training_flops(net.config, points)
        floor = batch * per_sample / rate.flops
        rates = {f"matmul_{'' if p == 'fp32' else p + '_'}gflops": r / 1e9
                 for p, r in rate.matmul.items()}  # fmt: skip
        rows.append(dict(
            name=f"{name} training step (forward + backward + Adam), batch {batch} x {points} "
            f"points, {kind}",
            ours=seconds, reference=floor, ratio=floor / seconds, target=None,
            samples_per_s=batch / seconds, floor=floor, floor_samples_per_s=batch / floor,
            floor_of_clock=batch * per_sample / rate.peak.flops, forward_flops=float(forward),
            train_flops=float(per_sample), batch=batch, points=points, threads=n_threads,
            precision=resolved, **rates,
            note=f"{batch / seconds:.1f} samples/s on {n_threads} thread"
            f"{'s' * (n_threads != 1)} vs the FLOP floor (reference) of "
            f"{batch / floor:.1f} samples/s: {floor * 1e3:.0f} ms = {batch} x 3 x "
            f"{forward / 1e9:.3g} GFLOP / {rate.describe()}",
        ))  # fmt: skip
    return rows
