"""The numbers of an evaluation as files: ``results.json`` and ``summary.csv``.

* ``results.json``: the settings, the skipped methods, the datasets, and every episode
  (:class:`nbv.eval.protocol.EpisodeRecord`; undefined VIG is ``null``).
* ``summary.csv``: one row per (dataset, viewspace, method, check): episodes, mean AUC and its
  standard error, mean coverage and VIG after each view, mean seconds per reconstruction, then
  the field's metrics (:mod:`nbv.eval.metric_tables`): final coverage, views to 90 % / 95 %
  (mean of the uncensored, censored count, restricted mean), Chamfer and F-scores, path
  lengths, seconds per decision of each stage, and the policy's tie counts when it has them.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from nbv.eval.metrics import REACH_FRACTIONS, mean_keys
from nbv.eval.statistics import (
    DECISION_STAGES,
    episode_values,
    groups,
    method_rank,
    summaries,
)
from nbv.policies.registry import (
    METHODS,
)
from nbv.utils.atomic import write_text


def _jsonable(value):
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def _cell(value) -> str:
    """A CSV cell: empty for a missing or undefined value."""
    return "" if value is None or not np.isfinite(value) else f"{value:.6g}"


def write_json(evaluation, path: Path) -> None:
    """``results.json``: settings, skipped methods, datasets, seconds, every episode."""
    head = {
        "settings": _jsonable(evaluation.settings.stored()),
        "skipped": evaluation.skipped,
        "datasets": [_jsonable(asdict(d)) for d in evaluation.datasets],
        "seconds": evaluation.seconds,
        "resumed_episodes": evaluation.resumed,
    }
    # One episode a line, without indentation: json's indenting encoder is pure Python and
    # took 4 s for the 10,096 episodes of the default run; the compact one is C.
    episodes = ",\n".join(
        json.dumps(_jsonable(r.to_json()), allow_nan=False) for r in evaluation.records
    )
    text = json.dumps(head, indent=1, allow_nan=False)
    write_text(path, f'{text[:-2]},\n "episodes": [\n{episodes}\n ]\n}}\n')


def metric_columns() -> tuple[str, ...]:
    """summary.csv's columns of the field's metrics (:func:`nbv.eval.statistics.summaries`):
    the metrics aggregated by their mean (:func:`nbv.eval.metrics.mean_keys`); ``views_to_<n>``
    the mean over uncensored episodes, ``censored_<n>`` how many were censored,
    ``restricted_<n>`` the mean with a censored episode counted ``n_views + 1``; ``stage_<s>``
    mean seconds of stage ``s`` per decision; ``ties`` and ``tie_decisions`` summed over
    episodes."""
    return (
        *mean_keys(),
        *(f"{k}_{n}" for n in REACH_FRACTIONS for k in ("views_to", "censored", "restricted")),
        "decisions",
        *(f"stage_{s}" for s in DECISION_STAGES),
        "ties",
        "tie_decisions",
    )


def write_csv(evaluation, path: Path) -> None:
    """``summary.csv``: one row per (dataset, viewspace, method, check)."""
    g = groups(evaluation.records, check=True)
    n_views = evaluation.settings.n_views
    header = ["dataset", "viewspace", "method", "check", "episodes", "repeats", "auc", "auc_se",
              "auc_low", "auc_high", "zero_gain_picks", "planned_picks"]  # fmt: skip
    header += [f"coverage_{i + 1}" for i in range(n_views)]
    header += [f"vig_{i + 1}" for i in range(n_views)]
    header += ["seconds_total", "seconds_online"]
    columns = metric_columns()
    header += list(columns)
    metrics = summaries(episode_values(evaluation.records, n_views))
    handle = io.StringIO()
    writer = csv.writer(handle, lineterminator="\n")
    writer.writerow(header)
    for (dataset, vs, method, check), s in sorted(
        g.items(), key=lambda kv: (kv[0][0], kv[0][1], method_rank(kv[0][2]), kv[0][3] or "")
    ):
        row = [dataset, vs, method, check or "", s["n"], s["repeats"], f"{s['auc']:.6f}"]
        row += ["" if not np.isfinite(x) else f"{x:.6f}"
                for x in (s["auc_se"], s["auc_ci"].low, s["auc_ci"].high)]  # fmt: skip
        planner = METHODS[method].geometric if method in METHODS else False
        row += [f"{s['zero_gain']:.4f}", f"{s['planned']:.4f}"] if planner else ["", ""]
        row += [f"{c:.6f}" for c in s["coverage"]]
        row += ["" if not np.isfinite(v) else f"{v:.6f}" for v in s["vig"]]
        row += [f"{s['total']:.6f}", f"{s['online']:.6f}"]
        m = metrics.get((dataset, vs, method, check))
        row += [_cell(m.get(c)) if m else "" for c in columns]
        writer.writerow(row)
    write_text(path, handle.getvalue())
