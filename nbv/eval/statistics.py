"""The evaluator's statistics: means over episodes and paired differences, free of Markdown.

By method, by view, by category, and paired differences between two methods. An *episode* is a
(model, start view) pair; a stochastic method's repeats of one episode are averaged first, so
every method counts each episode once. Intervals are 95 % bootstrap intervals that resample
models (the start views of one model are not independent), seeded. The report's order of the
methods (the registry's) is here too: the tables, the plots and the results files all use it.

The field's metrics (:mod:`nbv.eval.metrics`) by episode and group: views to reach 90 % / 95 %
of the viewspace's total coverage are censored when an episode never reaches it. The rule: the
mean is over the episodes that reach it, and the censored ones are counted beside it; a paired
difference uses the *restricted* count ``min(views, n_views + 1)``, a censored episode counting
``n_views + 1``. Every episode has the same length, so the restricted count is known exactly
for every episode (no survival model is needed): it is the restricted mean of the number of
views, over the episode's horizon. An undefined value (a Chamfer distance of an empty
reconstruction, NaN) is left out of its mean and of the pairs.

:func:`run_statistics` computes what the report shows once; :mod:`nbv.eval.tables`,
:mod:`nbv.eval.metric_tables` and :mod:`nbv.eval.report` write Markdown from it."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from nbv.eval.metrics import REACH_FRACTIONS, mean_keys
from nbv.policies.episode import auc
from nbv.policies.registry import METHODS
from nbv.utils.stats import Interval, bootstrap_mean


def repeat_mean(values: list) -> float:
    """The mean of one episode's repeats: the value itself for one repeat (most methods; as
    ``np.mean`` gives it, without its cost, which the report pays some 10^5 times)."""
    return float(values[0]) if len(values) == 1 else float(np.mean(values))


def episode_means(records: list) -> dict[tuple, dict[tuple[str, int], EpisodeMean]]:
    """Records by (dataset, viewspace, method, check), then by episode (model key, start view),
    a stochastic method's repeats averaged into one :class:`EpisodeMean` per episode."""
    by: dict[tuple, dict[tuple[str, int], list]] = defaultdict(lambda: defaultdict(list))
    for r in records:
        by[(r.dataset, r.viewspace, r.method, r.check)][(r.key, r.start)].append(r)
    out: dict[tuple, dict[tuple[str, int], EpisodeMean]] = {}
    for group, episodes in by.items():
        out[group] = {}
        for episode, rs in episodes.items():
            coverage = np.array([r.coverage for r in rs], dtype=float)
            vig = np.array([r.vig for r in rs], dtype=float)
            out[group][episode] = EpisodeMean(
                auc=repeat_mean([r.auc for r in rs]),
                coverage=coverage[0] if len(rs) == 1 else coverage.mean(axis=0),
                vig=vig[0] if len(rs) == 1 else vig.mean(axis=0),
                total=repeat_mean([r.timings["total"] for r in rs]),
                online=repeat_mean([r.timings["online"] for r in rs]),
                zero_gain=repeat_mean([r.counts.get("zero_gain", 0) for r in rs]),
                planned=repeat_mean([r.counts.get("planned", 0) for r in rs]),
                repeats=len(rs),
            )
    return out


@dataclass(frozen=True)
class EpisodeMean:
    """One episode's numbers, averaged over a stochastic method's repeats (see
    :class:`nbv.eval.protocol.EpisodeRecord` for the fields)."""

    auc: float
    coverage: np.ndarray
    vig: np.ndarray
    total: float
    online: float
    zero_gain: float
    planned: float
    repeats: int

    @property
    def vig_auc(self) -> float:
        """The AUC of the VIG curve (coverage's formula, :func:`nbv.policies.episode.auc`);
        NaN where VIG is undefined after some view."""
        return auc(self.vig)


def groups(records: list, check: bool = False, seed: int = 0) -> dict[tuple, dict]:
    """Means over episodes, by (dataset, viewspace, method, check).

    Args:
        records: episode records.
        check: keep the disturbance checks too (otherwise only the methods as they are).
        seed: the bootstrap's seed.

    Returns:
        key -> ``n`` (episodes), ``repeats`` (seeds per episode), ``auc`` (mean), ``auc_se``,
        ``auc_ci`` (:class:`nbv.utils.stats.Interval`, models resampled), ``coverage`` and
        ``vig`` (mean curves; VIG averages the models where it is defined, NaN if none),
        ``total`` and ``online`` (mean seconds per reconstruction), ``zero_gain`` and
        ``planned`` (mean picks per episode).
    """
    out = {}
    for key, episodes in episode_means(records).items():
        if key[3] is not None and not check:
            continue
        eps = list(episodes.values())
        aucs = np.array([e.auc for e in eps])
        vig = np.array([e.vig for e in eps], dtype=float)
        defined = np.isfinite(vig).all(axis=1)
        out[key] = dict(
            n=len(eps),
            repeats=max(e.repeats for e in eps),
            auc=float(aucs.mean()),
            auc_se=float(aucs.std(ddof=1) / np.sqrt(len(eps))) if len(eps) > 1 else float("nan"),
            auc_ci=bootstrap_mean(aucs, [k for k, _ in episodes], seed),
            coverage=np.mean([e.coverage for e in eps], axis=0),
            vig=vig[defined].mean(axis=0) if defined.any() else np.full(vig.shape[1], np.nan),
            total=float(np.mean([e.total for e in eps])),
            online=float(np.mean([e.online for e in eps])),
            zero_gain=float(np.mean([e.zero_gain for e in eps])),
            planned=float(np.mean([e.planned for e in eps])),
        )
    return out


def method_rank(method: str) -> int:
    """Position of a method in report order (the registry's; unknown names last)."""
    order = list(METHODS)
    return order.index(method) if method in order else len(order)


def order_methods(methods) -> list[str]:
    """Distinct method names in report order."""
    return sorted(set(methods), key=method_rank)


@dataclass(frozen=True)
class PairedDifference:
    """B - A over the episodes both ran: the interval, and each side's mean there."""

    interval: Interval
    mean_a: float
    mean_b: float


def paired_from_means(
    means: dict, a: tuple, b: tuple, seed: int = 0, what: str = "auc"
) -> PairedDifference | None:
    """AUC(b) - AUC(a) (of coverage, or of the VIG curve) over the episodes both ran, with a
    bootstrap interval (models resampled).

    Args:
        means: :func:`episode_means` of the records (computed once for many pairs: it is the
            costly part).
        a, b: the (dataset, viewspace, method, check or None) keys of each side.
        seed: the bootstrap's seed.
        what: the :class:`EpisodeMean` value compared: ``auc`` (coverage's) or ``vig_auc``
            (the VIG curve's); episodes where either side's is NaN are left out.

    Returns:
        None when no episode is shared.
    """
    ea, eb = means.get(a, {}), means.get(b, {})
    pairs = [(getattr(ea[e], what), getattr(eb[e], what), e) for e in sorted(set(ea) & set(eb))]
    pairs = [p for p in pairs if np.isfinite(p[0]) and np.isfinite(p[1])]
    if not pairs:
        return None
    xa = np.array([p[0] for p in pairs])
    xb = np.array([p[1] for p in pairs])
    shared = [p[2] for p in pairs]
    return PairedDifference(
        bootstrap_mean(xb - xa, [k for k, _ in shared], seed), float(xa.mean()), float(xb.mean())
    )


#: The timing stages, summed over the columns of the per-decision table: ``map update``
#: builds what the method scores from (the occupancy map, the sampled cloud, the signature, the
#: hull), ``scoring`` scores the candidates (gains, the network, the view simulation, the cover).
MAP_STAGES = ("map", "sampling", "signature", "hull")
SCORING_STAGES = ("gains", "network", "simulation", "set_cover")
DECISION_STAGES = (*MAP_STAGES, *SCORING_STAGES)


def _number(value) -> float:
    return float("nan") if value is None else float(value)


def episode_values(records: list, n_views: int) -> dict[tuple, dict[tuple[str, int], dict]]:
    """Each episode's metrics, a stochastic method's repeats averaged.

    Args:
        records: episode records with their ``metrics`` (those without are left out).
        n_views: the episodes' length (a censored views-to-reach counts ``n_views + 1``).

    Returns:
        (dataset, viewspace, method, check) -> (model key, start) -> metric -> value: the keys of
        ``mean_keys()``, ``views_to_<n>`` (restricted, see the module docstring),
        ``reached_<n>`` (mean views of the repeats that reached it, NaN if none did),
        ``censored_<n>`` (the fraction of repeats censored), ``decisions``, ``stage_<s>``
        (seconds of stage ``s`` per decision), ``ties`` and ``tie_decisions`` (the summed
        ``counts`` of ties and decisions, NaN when the policy records none).
    """
    by: dict[tuple, dict[tuple[str, int], list]] = defaultdict(lambda: defaultdict(list))
    for r in records:
        if r.metrics:
            by[(r.dataset, r.viewspace, r.method, r.check)][(r.key, r.start)].append(r)
    out: dict[tuple, dict[tuple[str, int], dict]] = {}
    for group, episodes in by.items():
        out[group] = {}
        for episode, rs in episodes.items():
            row = {k: repeat_mean([_number(r.metrics.get(k)) for r in rs]) for k in mean_keys()}
            for n in REACH_FRACTIONS:
                got = [r.metrics.get(f"views_to_{n}") for r in rs]
                row[f"views_to_{n}"] = repeat_mean([n_views + 1 if v is None else v for v in got])
                reached = [v for v in got if v is not None]
                row[f"reached_{n}"] = repeat_mean(reached) if reached else float("nan")
                row[f"censored_{n}"] = repeat_mean([v is None for v in got])
            decisions = [max(1, len(r.decision_times)) for r in rs]
            row["decisions"] = repeat_mean(decisions)
            for s in DECISION_STAGES:
                row[f"stage_{s}"] = repeat_mean(
                    [r.timings.get(s, 0.0) / d for r, d in zip(rs, decisions, strict=True)]
                )
            for k, name in (("ties", "ties"), ("decisions", "tie_decisions")):
                have = [r.counts[k] for r in rs if k in r.counts]
                row[name] = repeat_mean(have) if have else float("nan")
            out[group][episode] = row
    return out


def mean_finite(values) -> float:
    """The mean of the finite values (NaN when none)."""
    x = np.asarray(list(values), dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else float("nan")


def summaries(values: dict) -> dict[tuple, dict[str, float]]:
    """Means over the episodes of each group of :func:`episode_values`.

    Returns:
        group -> ``episodes``, each key of ``mean_keys()`` and ``stage_<s>``, ``decisions``;
        ``views_to_<n>`` (the mean over the episodes that reached it), ``censored_<n>`` (how many
        episodes were censored: a stochastic method's repeats count as fractions of one),
        ``restricted_<n>`` (the mean restricted count); ``ties`` and ``tie_decisions`` (sums
        over episodes, NaN when not recorded).
    """
    out = {}
    for group, episodes in values.items():
        rows = list(episodes.values())
        s = {"episodes": len(rows)}
        for k in (*mean_keys(), "decisions", *(f"stage_{x}" for x in DECISION_STAGES)):
            s[k] = mean_finite(r[k] for r in rows)
        for n in REACH_FRACTIONS:
            s[f"views_to_{n}"] = mean_finite(r[f"reached_{n}"] for r in rows)
            s[f"censored_{n}"] = float(sum(r[f"censored_{n}"] for r in rows))
            s[f"restricted_{n}"] = mean_finite(r[f"views_to_{n}"] for r in rows)
        for k in ("ties", "tie_decisions"):
            have = [r[k] for r in rows if np.isfinite(r[k])]
            s[k] = float(np.sum(have)) if have else float("nan")
        out[group] = s
    return out


def paired_metric(values: dict, a: tuple, b: tuple, key: str, seed: int = 0):
    """``key`` of group ``b`` minus group ``a`` over the episodes both ran where both are
    defined, with a bootstrap interval resampling models; None when none is shared."""
    ea, eb = values.get(a, {}), values.get(b, {})
    shared = [e for e in sorted(set(ea) & set(eb))
              if np.isfinite(ea[e][key]) and np.isfinite(eb[e][key])]  # fmt: skip
    if not shared:
        return None
    diff = np.array([eb[e][key] - ea[e][key] for e in shared])
    return bootstrap_mean(diff, [k for k, _ in shared], seed)


@dataclass(frozen=True)
class RunStatistics:
    """What the report's tables show of a run, computed once.

    Attributes:
        groups: :func:`groups` of the records (the undisturbed episodes).
        means: :func:`episode_means` of the undisturbed records.
        values: :func:`episode_values` of the undisturbed records (the metrics by episode).
        summary: :func:`summaries` of ``values``.
    """

    groups: dict
    means: dict
    values: dict
    summary: dict


def run_statistics(records: list, n_views: int) -> RunStatistics:
    """The :class:`RunStatistics` of a run's records (episodes of ``n_views`` views)."""
    undisturbed = [r for r in records if r.check is None]
    values = episode_values(undisturbed, n_views)
    return RunStatistics(groups(records), episode_means(undisturbed), values, summaries(values))
