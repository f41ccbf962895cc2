"""The report's tables of the field's metrics (:mod:`nbv.eval.metrics`), the seconds per
decision of each stage, and spread's ties.

Means per (dataset, viewspace, method) over episodes, a stochastic method's repeats averaged
first (as :func:`nbv.eval.statistics.episode_means` does for AUC); paired differences against spread
and random over the episodes both ran, with bootstrap intervals that resample models
(:func:`nbv.utils.stats.bootstrap_mean`, as AUC's).

Views to reach 90 % / 95 % of the viewspace's total coverage are censored when an episode never
reaches it. The rule: the mean is over the episodes that reach it, and the censored ones are
counted beside it; a paired difference uses the *restricted* count ``min(views, n_views + 1)``,
a censored episode counting ``n_views + 1``. Every episode has the same length, so the
restricted count is known exactly for every episode (no survival model is needed): it is the
restricted mean of the number of views, over the episode's horizon.

An undefined value (a Chamfer distance of an empty reconstruction, NaN) is left out of its mean
and of the pairs.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from nbv.eval.metrics import REACH_FRACTIONS, mean_keys, paired_metrics
from nbv.eval.statistics import method_rank, repeat_mean
from nbv.eval.tables import fmt
from nbv.policies.registry import RANDOM, SPREAD
from nbv.utils.markdown import md_table
from nbv.utils.stats import bootstrap_mean

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


def _mean(values) -> float:
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
            s[k] = _mean(r[k] for r in rows)
        for n in REACH_FRACTIONS:
            s[f"views_to_{n}"] = _mean(r[f"reached_{n}"] for r in rows)
            s[f"censored_{n}"] = float(sum(r[f"censored_{n}"] for r in rows))
            s[f"restricted_{n}"] = _mean(r[f"views_to_{n}"] for r in rows)
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


def _censored(count: float) -> str:
    return f"{count:.0f}" if float(count).is_integer() else f"{count:.1f}"


def metrics_tables(records, datasets, viewspaces, n_views: int, seed: int) -> list[str]:
    """The report's sections: the metrics' means per method, and each method minus spread and
    minus random with paired intervals; [] when no record has metrics."""
    values = episode_values([r for r in records if r.check is None], n_views)
    if not values:
        return []
    summary = summaries(values)
    lines = [
        "",
        "## Reconstruction, coverage and path metrics",
        "",
        "Means over episodes (a stochastic method's seeds averaged first). Final coverage: after "
        f"the {n_views} views. Views to 90 % / 95 %: the views (the start view counts) after "
        "which the episode first reaches that share of the coverage all the viewspace's views "
        "reach together; the mean over the episodes that reach it, and in brackets how many "
        "never did (censored). Chamfer: the accumulated cloud of the episode's views (the "
        "dataset's stored points) against the ground-truth points, in the normalised object "
        "frame (the object fits in radius 0.5): mean distance reconstruction to truth (acc.), "
        "truth to reconstruction (comp.), and their mean. F-score at the dataset's eps and "
        "2 eps. Path: the great-circle arcs between consecutive cameras at the viewspace's "
        "radius; shortest: the shortest path from the start view through the same views.",
    ]
    header = ["method", "episodes", "final coverage", "views to 90 %", "views to 95 %",
              "Chamfer acc.", "Chamfer comp.", "Chamfer", "F-score eps", "F-score 2 eps",
              "path", "shortest path"]  # fmt: skip
    for d in datasets:
        for vs in viewspaces:
            keys = sorted((k for k in summary if k[0] == d and k[1] == vs),
                          key=lambda k: method_rank(k[2]))  # fmt: skip
            if not keys:
                continue
            rows = []
            for k in keys:
                s = summary[k]
                reach = [f"{fmt(s[f'views_to_{n}'], 2)} ({_censored(s[f'censored_{n}'])})"
                         for n in REACH_FRACTIONS]  # fmt: skip
                rows.append(
                    [k[2], str(s["episodes"]), fmt(s["final_coverage"]), *reach,
                     fmt(s["chamfer_accuracy"], 4), fmt(s["chamfer_completeness"], 4),
                     fmt(s["chamfer"], 4), fmt(s["fscore_eps"]), fmt(s["fscore_2eps"]),
                     fmt(s["path_length"], 2), fmt(s["shortest_path"], 2)]
                )  # fmt: skip
            lines += [f"\n**{d}, {vs} viewspace**\n"]
            lines += md_table(header, rows)
    for base in (SPREAD.name, RANDOM.name):
        lines += _paired_section(values, base, datasets, viewspaces, n_views, seed)
    return lines


def _paired_section(values, base, datasets, viewspaces, n_views, seed) -> list[str]:
    lines = []
    paired = paired_metrics()
    for d in datasets:
        for vs in viewspaces:
            a = (d, vs, base, None)
            if a not in values:
                continue
            others = sorted((k for k in values if k[:2] == (d, vs) and k[2] != base),
                            key=lambda k: method_rank(k[2]))  # fmt: skip
            rows = []
            for b in others:
                cells = []
                for m in paired:
                    diff = paired_metric(values, a, b, m.key, seed)
                    cells.append(diff.text(m.digits) if diff else "")
                rows.append([b[2], *cells])
            if not rows:
                continue
            if not lines:
                lines += [
                    "",
                    f"## The metrics minus {base}, paired over the same episodes",
                    "",
                    f"Mean [95 % bootstrap interval, models resampled] of metric(method) - "
                    f"metric({base}) per episode. Lower is better for views to reach, Chamfer "
                    f"and path. Views to reach: a censored episode counts {n_views + 1} views "
                    f"(the restricted count; see the table above for the censored episodes).",
                ]
            lines += [f"\n**{d}, {vs} viewspace**\n"]
            lines += md_table(["method", *(m.title for m in paired)], rows)
    return lines


def decision_table(records, methods, n_views: int) -> list[str]:
    """Mean seconds per decision of each stage a method has, map update and scoring apart."""
    values = episode_values([r for r in records if r.check is None], n_views)
    by: dict[str, list[dict]] = defaultdict(list)
    for (_, _, m, _), episodes in values.items():
        by[m] += list(episodes.values())
    if not by:
        return []
    stages = [s for s in DECISION_STAGES if any(_mean(r[f"stage_{s}"] for r in by[m]) > 0
                                                for m in by)]  # fmt: skip
    rows = []
    for m in [m for m in methods if m in by]:
        mean = {s: _mean(r[f"stage_{s}"] for r in by[m]) for s in DECISION_STAGES}
        map_s = sum(mean[s] for s in MAP_STAGES)
        score_s = sum(mean[s] for s in SCORING_STAGES)
        rows.append([m, fmt(_mean(r["decisions"] for r in by[m]), 1)]
                    + [fmt(mean[s], 4) if mean[s] > 0 else "" for s in stages]
                    + [fmt(map_s, 4) if map_s > 0 else "",
                       fmt(score_s, 4) if score_s > 0 else ""])  # fmt: skip
    return [
        "",
        "## Seconds per decision, map update and scoring",
        "",
        "Mean seconds of each stage per decision (a one-shot plan is one decision; a stage a "
        "method runs only at some decisions counts 0 at the others), over all undisturbed "
        f"episodes. Map update = {' + '.join(MAP_STAGES)} (what the method builds from the "
        f"captured cloud); scoring = {' + '.join(SCORING_STAGES)} (scoring the candidates). "
        "A blank: the method has no such stage.",
        "",
        *md_table(["method", "decisions an episode", *stages, "map update", "scoring"], rows),
    ]


def tie_lines(records, datasets, viewspaces, n_views: int) -> list[str]:
    """How many of spread's decisions were ties, per dataset and viewspace (its policy's
    ``counts["ties"]`` of ``counts["decisions"]``); [] when spread records no ties."""
    values = episode_values(
        [r for r in records if r.check is None and r.method == SPREAD.name], n_views
    )
    summary = summaries(values)
    rows = []
    for d in datasets:
        for vs in viewspaces:
            s = summary.get((d, vs, SPREAD.name, None))
            if s is None or not np.isfinite(s["ties"]) or not np.isfinite(s["tie_decisions"]):
                continue
            share = s["ties"] / s["tie_decisions"] if s["tie_decisions"] else float("nan")
            rows.append([d, vs, str(s["episodes"]), f"{s['ties']:g}", f"{s['tie_decisions']:g}",
                         fmt(100 * share, 1)])  # fmt: skip
    if not rows:
        return []
    return [
        "",
        "## Spread's ties",
        "",
        "Decisions of spread at which more than one unvisited view was farthest in angle from "
        "the visited ones (within its tolerance), of all its decisions, summed over its "
        "episodes (the seeds of an episode averaged first).",
        "",
        *md_table(
            ["dataset", "viewspace", "episodes", "tied decisions", "decisions", "% tied"], rows
        ),  # fmt: skip
    ]
