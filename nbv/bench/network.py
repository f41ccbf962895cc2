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

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from nbv.bench.timing import best_time
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
