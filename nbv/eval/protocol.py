"""The evaluation protocol: seeds and one episode's record.

An episode starts from a start view and lets a method pick views until ``n_views`` are captured
(:func:`nbv.policies.episode.run_episode`); coverage and VIG after each view come from the model's
ground truth (:func:`nbv.policies.episode.curves`), the AUC is PC-NBV's. Every episode gets its own
generator, seeded by the run's seed and the names of the method, check, model, viewspace and the
start view, so a result does not depend on which other episodes ran.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from nbv.dataset.records import ModelData
from nbv.policies.episode import Episode, stage_seconds
from nbv.utils.seeding import named_rng


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
            :mod:`nbv.policies`), plus ``total`` (all decision times) and ``online`` (total
            without the view simulation, the paper's "online" time).
        notes: what the policy had to work around.
        repeat: which seed of a stochastic method's episode (0 for the others).
        counts: the policy's counts (a planner's ``planned``, ``zero_gain``; empty for a
            method that counts nothing).
        metrics: the field's metrics of the episode (final coverage, views to 90 % and 95 % of
            the viewspace's total coverage, Chamfer distance and F-scores, camera path length:
            :mod:`nbv.eval.metrics`); empty for a record read back from a log written before
            they existed, until :func:`nbv.eval.metrics.fill_metrics` computes them.
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
    repeat: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """Plain JSON types; NaN becomes None. Shallow: the lists and dicts are the record's own
        (``dataclasses.asdict``'s deep copy was a tenth of the report's time)."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
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
    return named_rng(seed, *names)


def episode_timings(policy, decision_times: list[float]) -> dict[str, float]:
    """Seconds per stage summed over an episode, with ``total`` and ``online``."""
    out = stage_seconds(policy)
    out["total"] = float(np.sum(decision_times))
    out["online"] = out["total"] - out.get("simulation", 0.0)
    return out


def episode_record(
    model: ModelData,
    viewspace: str,
    start: int,
    method: str,
    policy,
    dataset: str,
    episode: Episode,
    check: str | None = None,
    repeat: int = 0,
) -> EpisodeRecord:
    """The record of an episode ``policy`` ran (:func:`run_episode` or
    :func:`nbv.policies.lockstep.run_lockstep`)."""
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
        notes=sorted(set(policy.notes) | set(episode.notes)),
        repeat=int(repeat),
        counts=dict(policy.counts),
    )
