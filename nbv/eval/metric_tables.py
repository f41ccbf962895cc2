"""The report's Markdown of the field's metrics (:mod:`nbv.eval.metrics`), the seconds per
decision of each stage, and spread's ties, written from :class:`nbv.eval.statistics.RunStatistics`
(means per (dataset, viewspace, method) over episodes, a stochastic method's repeats averaged
first; paired differences against spread and random over the episodes both ran, with bootstrap
intervals that resample models; the censoring rule of views to reach is the statistics').
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from nbv.eval.metrics import Metric, paired_metrics, tabled_metrics
from nbv.eval.statistics import (
    DECISION_STAGES,
    MAP_STAGES,
    SCORING_STAGES,
    RunStatistics,
    mean_finite,
    method_rank,
    paired_metric,
)
from nbv.eval.tables import fmt
from nbv.policies.registry import RANDOM, SPREAD
from nbv.utils.markdown import md_table


def _censored(count: float) -> str:
    return f"{count:.0f}" if float(count).is_integer() else f"{count:.1f}"


def _mean_cell(metric: Metric, s: dict) -> str:
    """A metric's cell in the table of means: a censored one's mean over the episodes that
    reach it, with how many never did in brackets."""
    if metric.aggregate == "censored":
        count = s[f"censored_{metric.key.rsplit('_', 1)[1]}"]
        return f"{fmt(s[metric.key], metric.digits)} ({_censored(count)})"
    return fmt(s[metric.key], metric.table_digits or metric.digits)


def metrics_tables(
    stats: RunStatistics, datasets, viewspaces, n_views: int, seed: int
) -> list[str]:
    """The report's sections: the metrics' means per method, and each method minus spread and
    minus random with paired intervals; [] when no record has metrics."""
    values, summary = stats.values, stats.summary
    if not values:
        return []
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
    tabled = tabled_metrics()
    header = ["method", "episodes", *(m.title for m in tabled)]
    for d in datasets:
        for vs in viewspaces:
            keys = sorted((k for k in summary if k[0] == d and k[1] == vs),
                          key=lambda k: method_rank(k[2]))  # fmt: skip
            if not keys:
                continue
            rows = []
            for k in keys:
                s = summary[k]
                rows.append([k[2], str(s["episodes"]), *(_mean_cell(m, s) for m in tabled)])
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


def decision_table(stats: RunStatistics, methods) -> list[str]:
    """Mean seconds per decision of each stage a method has, map update and scoring apart."""
    by: dict[str, list[dict]] = defaultdict(list)
    for (_, _, m, _), episodes in stats.values.items():
        by[m] += list(episodes.values())
    if not by:
        return []
    stages = [s for s in DECISION_STAGES if any(mean_finite(r[f"stage_{s}"] for r in by[m]) > 0
                                                for m in by)]  # fmt: skip
    rows = []
    for m in [m for m in methods if m in by]:
        mean = {s: mean_finite(r[f"stage_{s}"] for r in by[m]) for s in DECISION_STAGES}
        map_s = sum(mean[s] for s in MAP_STAGES)
        score_s = sum(mean[s] for s in SCORING_STAGES)
        rows.append([m, fmt(mean_finite(r["decisions"] for r in by[m]), 1)]
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


def tie_lines(stats: RunStatistics, datasets, viewspaces) -> list[str]:
    """How many of spread's decisions were ties, per dataset and viewspace (its policy's
    ``counts["ties"]`` of ``counts["decisions"]``); [] when spread records no ties."""
    summary = stats.summary
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
