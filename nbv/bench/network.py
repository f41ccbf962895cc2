"""Time one 9-view episode of PCNBV (or PCNBV-sph) inference, sampling included (rows of
``make bench``).

An episode starts from one captured view and asks the network nine times for the next view; each
decision farthest-point samples the accumulated cloud to the network's points (or computes its
spherical signature) and runs one forward pass. The project's path is
:class:`nbv.policies.network.NetworkPolicy` on the inference copy of the network
(:func:`nbv.models.inference.for_inference`: batch norm folded, bfloat16 where the CPU runs it
natively, subnormals flushed); the reference is the plain float32 network called the same way.

Untrained weights cost what trained ones cost only because subnormals are flushed in the
project's path; pass a trained checkpoint (``python -m nbv.bench checkpoint=best.pt``) to time
the reference on trained weights too.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from nbv.bench.timing import best_time, torch_threads
from nbv.geometry.clouds import farthest_points
from nbv.geometry.sph import signature
from nbv.policies.episode import EPISODE_VIEWS


def network_episode(
    decide: Callable[[np.ndarray, np.ndarray], int],
    views: Sequence[np.ndarray],
    start: int,
    n_views: int = EPISODE_VIEWS,
) -> list[int]:
    """Run ``decide(cloud (N, 3), view_state (V,) bool) -> view`` from ``start`` until
    ``n_views`` views are captured; ``views`` holds each candidate view's (M, 3) points.
    Returns the captured views in order."""
    state = np.zeros(len(views), dtype=bool)
    order = [start]
    state[start] = True
    while len(order) < n_views:
        v = int(decide(np.concatenate([views[i] for i in order]), state))
        if state[v]:
            raise ValueError(f"the policy chose the visited view {v}")
        state[v] = True
        order.append(v)
    return order


def load_network(checkpoint: Path | None, n_views: int = 33):
    """A trained network from ``checkpoint``, or a freshly initialised one (seed 0) when None;
    in eval mode."""
    import torch

    from nbv.models.checkpoints import load_checkpoint
    from nbv.models.config import PCNBVConfig
    from nbv.models.pcnbv import PCNBV

    if checkpoint is not None:
        net, _ = load_checkpoint(checkpoint, n_views=n_views)
        return net.eval()
    torch.manual_seed(0)
    return PCNBV(PCNBVConfig(n_views=n_views)).eval()


def plain_decider(
    net, n_points: int, input: str = "points", lmax: int = 3
) -> Callable[[np.ndarray, np.ndarray], int]:
    """The reference decision: farthest point sampling (``input="signature"``: the spherical
    signature of degree ``lmax``) and a plain float32 forward pass."""
    import torch

    from nbv.models.inference import masked_argmax

    def features(cloud: np.ndarray) -> np.ndarray:
        return signature(cloud, lmax) if input == "signature" else farthest_points(cloud, n_points)

    def decide(cloud: np.ndarray, state: np.ndarray) -> int:
        x = torch.from_numpy(np.ascontiguousarray(features(cloud), np.float32))
        s = torch.from_numpy(state)[None]
        with torch.no_grad():
            return int(masked_argmax(net(x[None], s.float()), s)[0])

    return decide


def episode_seconds(
    views: Sequence[np.ndarray],
    checkpoint: Path | None = None,
    start: int = 1,
    n_points: int = 512,
    repeat: int = 5,
) -> dict[str, float]:
    """Best wall time of a whole episode over ``repeat`` runs, for the project's path
    (``"ours"``) and the plain float32 network (``"reference"``), in seconds. A checkpoint of
    PCNBV-sph (its ``input`` is ``signature``) times signature episodes."""
    from nbv.models.inference import for_inference
    from nbv.policies.network import NetworkPolicy

    net = load_network(checkpoint, len(views))
    kind = NetworkPolicy.from_checkpoint(checkpoint, len(views)) if checkpoint else None
    policy = NetworkPolicy(
        for_inference(net, "auto"), input=kind.input if kind else "points", n_points=n_points,
        lmax=kind.lmax if kind else 3, precision="auto",
    )  # fmt: skip
    reference = plain_decider(net, n_points, policy.input, policy.lmax)
    deciders = {"ours": policy.decide, "reference": reference}
    out = {}
    # numpy's BLAS on one thread beside torch's, as in an evaluation worker (two pools on two
    # cores slow the signature step several times); both sides alike.
    with threadpool_limits(limits=1, user_api="blas"):
        for name, decide in deciders.items():
            network_episode(decide, views, start)  # warm-up: first calls allocate, pick kernels
            out[name] = best_time(lambda d=decide: network_episode(d, views, start), repeat, np.inf)
    return out


def lockstep_episodes(
    decide_many: Callable[[list[np.ndarray], list[np.ndarray]], list[int]],
    views: Sequence[np.ndarray],
    starts: Sequence[int],
    n_views: int = EPISODE_VIEWS,
) -> list[list[int]]:
    """Episodes from every view of ``starts`` stepped together, as the evaluator steps a model's
    episodes: each step one ``decide_many(clouds, view_states) -> views`` for all of them.
    Returns each episode's captured views in order."""
    orders = [[int(s)] for s in starts]
    states = [np.zeros(len(views), dtype=bool) for _ in starts]
    for state, start in zip(states, starts, strict=True):
        state[start] = True
    for _ in range(n_views - 1):
        clouds = [np.concatenate([views[i] for i in order]) for order in orders]
        for order, state, v in zip(orders, states, decide_many(clouds, states), strict=True):
            if state[v]:
                raise ValueError(f"the policy chose the visited view {v}")
            state[v] = True
            order.append(int(v))
    return orders


def input_points(policy) -> int:
    """Points one sample of a :class:`~nbv.policies.network.NetworkPolicy`'s network holds: its
    ``n_points``, or the ``4 (lmax+1)^2`` of a spherical signature."""
    return 4 * (policy.lmax + 1) ** 2 if policy.input == "signature" else policy.n_points


def _policy(checkpoint: Path, n_views: int, precision: str):
    from nbv.policies.network import NetworkPolicy

    return NetworkPolicy.from_checkpoint(checkpoint, n_views, precision=precision)


def batched_seconds(
    views: Sequence[np.ndarray],
    checkpoint: Path,
    starts: Sequence[int],
    repeat: int = 3,
    threads: int | None = None,
) -> dict[str, float]:
    """Seconds an episode in float32, for the episodes of ``starts`` in lockstep with one batched
    forward a step (``"batched"``, the whole over the number of episodes) and one at a time
    (``"single"``, their mean), best of ``repeat``, on ``threads`` torch threads (None: the
    process's); ``"forward_flops"``: FLOPs of one forward pass of one sample as the evaluator
    runs it (:func:`nbv.bench.floor.inference_flops`), and ``"written_flops"`` of the network
    as written (:func:`nbv.bench.floor.pcnbv_flops`).

    Raises:
        AssertionError: the two ways chose different views.
    """
    from nbv.bench.floor import inference_flops, pcnbv_flops

    policy = _policy(checkpoint, len(views), "fp32")
    n = len(starts)

    def batched() -> list[list[int]]:
        return lockstep_episodes(policy.decide_many, views, starts)

    def single() -> list[list[int]]:
        return [network_episode(policy.decide, views, s) for s in starts]

    with threadpool_limits(limits=1, user_api="blas"), torch_threads(threads):
        if batched() != single():  # also the warm-up
            raise AssertionError("batched and one-at-a-time episodes chose different views")
        out = {name: best_time(fn, repeat, np.inf) / n for name, fn in
               (("batched", batched), ("single", single))}  # fmt: skip
    points = input_points(policy)
    out["forward_flops"] = float(inference_flops(policy.model.config, points))
    out["written_flops"] = float(pcnbv_flops(policy.model.config, points))
    return out


@contextmanager
def busy_process() -> Iterator[subprocess.Popen]:
    """A CPU-bound process (a Python busy loop) for the block's duration, killed after: what
    another job on the machine does to the cores."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.2)  # let it start and take its core
        yield proc
    finally:
        proc.kill()
        proc.wait()


def load_seconds(
    views: Sequence[np.ndarray], checkpoint: Path, start: int = 1, repeat: int = 3
) -> dict[str, float]:
    """Best seconds of a one-at-a-time episode of the project's path (precision ``auto``) on the
    quiet machine (``"quiet"``) and beside :func:`busy_process` (``"busy"``), ``repeat`` pairs
    interleaved so that both see the same machine."""
    policy = _policy(checkpoint, len(views), "auto")

    def episode() -> list[int]:
        return network_episode(policy.decide, views, start)

    quiet, busy = [], []
    with threadpool_limits(limits=1, user_api="blas"):
        episode()  # warm-up
        for _ in range(repeat):
            quiet.append(best_time(episode, 1, np.inf))
            with busy_process():
                busy.append(best_time(episode, 1, np.inf))
    return {"quiet": min(quiet), "busy": min(busy)}


#: The slowdown beside a busy process the load rows aim at (issue 31).
LOAD_TARGET = 1.5
#: The start views of the lockstep rows: the evaluation protocol's.
LOCKSTEP_STARTS = (1, 3, 7, 10, 15, 24, 27, 30)


def network_rows(
    views: Sequence[np.ndarray],
    episodes: Sequence[tuple[str, Path, float | None]],
    starts: Sequence[int] = LOCKSTEP_STARTS,
    repeat: int = 3,
) -> list[dict]:
    """The network rows of ``make bench`` for each ``(name, checkpoint, target seconds)`` of
    ``episodes``: the 9-view episode against the plain float32 network, the episodes of
    ``starts`` batched against one at a time (float32) beside the FLOP floor of this machine
    (:mod:`nbv.bench.floor`), on the process's torch threads and on one (as an evaluation
    worker runs them: one worker a core), and the episode beside a busy process against the
    quiet machine.
    Rows: dicts of name, ours, reference, ratio, target (seconds), note; the batched rows also
    ``floor`` (seconds an episode, at the higher of the clock's peak and the measured rate of a
    matrix product, ``matmul_gflops``), ``floor_as_written`` and ``floor_of_clock`` (at the
    clock's peak alone), the load rows ``slowdown``."""
    from nbv.bench.floor import floor_rate

    rows = []
    for name, weights, target in episodes:
        t = episode_seconds(views, weights, repeat=max(repeat, 1))
        rows.append(dict(
            name=f"{name} 9-view episode (sampling + forwards)", ours=t["ours"],
            reference=t["reference"], ratio=t["reference"] / t["ours"], target=target,
            note=f"inference copy vs plain float32 network, weights {weights.name}",
        ))  # fmt: skip
    # On the process's threads, and on one as each evaluation worker runs (one worker a core).
    for threads in (None, 1):
        # The floor's rate: the clock formula's peak, or what a matrix product reaches here on
        # these threads when the core runs faster than the clock the machine reports.
        rate = floor_rate(threads)
        on = "" if threads is None else f", {threads} thread as an evaluation worker"
        for name, weights, target in episodes:
            t = batched_seconds(views, weights, starts, repeat, threads)
            forwards = EPISODE_VIEWS - 1
            floor = forwards * t["forward_flops"] / rate.flops
            written = forwards * t["written_flops"] / rate.flops
            clock = forwards * t["forward_flops"] / rate.peak.flops
            rows.append(dict(
                name=f"{name} episodes, {len(starts)} in lockstep, float32{on} (per episode)",
                ours=t["batched"], reference=t["single"], ratio=t["single"] / t["batched"],
                target=target, floor=floor, floor_as_written=written, floor_of_clock=clock,
                matmul_gflops=rate.matmul["fp32"] / 1e9,
                note=f"one batched forward a step vs one at a time; FLOP floor "
                f"{floor * 1e3:.0f} ms = {EPISODE_VIEWS - 1} x {t['forward_flops'] / 1e9:.3g} "
                f"GFLOP / {rate.describe()}; "
                f"the network as written: {t['written_flops'] / 1e9:.3g} GFLOP, "
                f"{written * 1e3:.0f} ms",
            ))  # fmt: skip
    for name, weights, _ in episodes:
        t = load_seconds(views, weights, repeat=repeat)
        slowdown = t["busy"] / t["quiet"]
        rows.append(dict(
            name=f"{name} 9-view episode beside a busy process",
            ours=t["busy"], reference=t["quiet"], ratio=t["quiet"] / t["busy"],
            target=LOAD_TARGET * t["quiet"], slowdown=slowdown,
            note=f"beside a CPU-bound process vs the quiet machine (reference), interleaved: "
            f"{slowdown:.2f}x slower; target {LOAD_TARGET}x the quiet time",
        ))  # fmt: skip
    return rows
