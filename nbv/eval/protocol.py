"""The evaluation protocol: which policy a method name means, seeds, and one episode's record.

An episode starts from a start view and lets a method pick views until ``n_views`` are captured
(:func:`nbv.policies.episode.run_episode`); coverage and VIG after each view come from the model's
ground truth (:func:`nbv.policies.episode.curves`), the AUC is PC-NBV's. Every episode gets its own
generator, seeded by the run's seed and the names of the method, check, model, viewspace and the
start view, so a result does not depend on which other episodes ran.
"""

from __future__ import annotations

import zlib
from dataclasses import asdict, dataclass, field

import numpy as np

from nbv.dataset.records import ModelData
from nbv.eval.config import HullSettings
from nbv.geometry.camera import Intrinsics
from nbv.policies.baselines import OraclePolicy, RandomPolicy
from nbv.policies.episode import run_episode
from nbv.policies.hull import HullSCOPolicy, HullSCOReplanPolicy
from nbv.policies.network import NetworkPolicy


@dataclass
class EpisodeRecord:
    """One episode of the evaluation, as written to ``results.json``.

    Attributes:
        method: the method name (``pcnbv``, ``hull_sco``, ...).
        check: the disturbance check, or None for the method as it is.
        dataset: ``unseen``, ``test`` or ``meshes``.
        viewspace: ``original`` or ``permuted``.
        key, category: the model.
        start: the start view.
        views: the captured views in order (start first).
        coverage, vig: coverage and VIG after each view (VIG NaN when the ground truth is flat).
        auc: PC-NBV's AUC of the coverage curve.
        decision_times: seconds of each call of the policy.
        timings: seconds per stage, summed over the episode's decisions (see
            :mod:`nbv.policies.policies`), plus ``total`` (all decision times) and ``online`` (total
            without the view simulation, the paper's "online" time).
        notes: what the policy had to work around.
    """

    method: str
    check: str | None
    dataset: str
    viewspace: str
    key: str
    category: str
    start: int
    views: list[int]
    coverage: list[float]
    vig: list[float]
    auc: float
    decision_times: list[float]
    timings: dict[str, float]
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        """Plain JSON types; NaN becomes None."""
        out = asdict(self)
        out["vig"] = [None if not np.isfinite(v) else v for v in self.vig]
        return out

    @classmethod
    def from_json(cls, values: dict) -> EpisodeRecord:
        """The inverse of :meth:`to_json` (None in ``vig`` becomes NaN)."""
        values = dict(values)
        values["vig"] = [np.nan if v is None else float(v) for v in values["vig"]]
        return cls(**values)


def episode_rng(seed: int, *names: str | int) -> np.random.Generator:
    """A generator seeded by ``seed`` and names (strings hashed with CRC-32, ints as they are)."""
    words = [int(seed)] + [zlib.crc32(n.encode()) if isinstance(n, str) else int(n) for n in names]
    return np.random.default_rng(words)


@dataclass
class Context:
    """What the policies of one dataset need besides a generator.

    Attributes:
        networks: method name -> a loaded :class:`NetworkPolicy` (the methods not skipped).
        hull: the convex-hull settings.
        intrinsics: the dataset's camera.
        eps: the dataset's coverage distance (the hull planner's capture distance: of the
            raycast simulation, and of the analytic one's dilation with ``hull.dilate``).
        n_views: views per episode.
    """

    networks: dict[str, NetworkPolicy]
    hull: HullSettings
    intrinsics: Intrinsics
    eps: float
    n_views: int


def make_policy(method: str, ctx: Context, rng: np.random.Generator):
    """A fresh policy for one episode of ``method`` (its ``timings`` start empty)."""
    if method == "random":
        return RandomPolicy(rng)
    if method == "oracle":
        return OraclePolicy("coverage")
    if method in ("pcnbv", "pcnbv_sph"):
        return ctx.networks[method].fresh()
    hull = ctx.hull
    common = dict(
        rng=rng,
        lmax=hull.lmax,
        n_views=ctx.n_views,
        n_samp=hull.n_samp,
        method=hull.simulation,
        dilate=hull.dilate,
        intrinsics=ctx.intrinsics,
        eps=ctx.eps,
        probe_points=hull.probe_points,
    )
    if method == "hull_sco":
        return HullSCOPolicy(**common)
    if method == "hull_sco_sph":
        return HullSCOPolicy(sph=True, **common)
    if method == "hull_sco_probes":
        return HullSCOPolicy(probes=hull.probes, **common)
    if method == "hull_sco_replan":
        return HullSCOReplanPolicy(**common)
    raise ValueError(f"unknown method {method!r}")


def episode_timings(policy, decision_times: list[float]) -> dict[str, float]:
    """Seconds per stage summed over an episode, with ``total`` and ``online``."""
    out = {k: float(np.sum(v)) for k, v in getattr(policy, "timings", {}).items()}
    out["total"] = float(np.sum(decision_times))
    out["online"] = out["total"] - out.get("simulation", 0.0)
    return out


def run_record(
    model: ModelData,
    viewspace: str,
    start: int,
    method: str,
    policy,
    dataset: str,
    n_views: int,
    check: str | None = None,
) -> EpisodeRecord:
    """Run one episode of ``policy`` and record it."""
    episode = run_episode(model, viewspace, start, policy, n_views=n_views)
    return EpisodeRecord(
        method=method,
        check=check,
        dataset=dataset,
        viewspace=viewspace,
        key=model.key,
        category=model.category,
        start=int(start),
        views=[int(v) for v in episode.views],
        coverage=[float(c) for c in episode.coverage],
        vig=[float(v) for v in episode.vig],
        auc=episode.auc,
        decision_times=[float(t) for t in episode.times],
        timings=episode_timings(policy, episode.times),
        notes=sorted(set(getattr(policy, "notes", []))),
    )
