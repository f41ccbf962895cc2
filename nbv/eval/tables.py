"""The Markdown tables of the report: curves by view, AUC by category, one row per method.

The numbers come from :mod:`nbv.eval.statistics`."""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from nbv.eval.statistics import method_rank, order_methods
from nbv.utils.markdown import md_table


def fmt(x: float, digits: int = 3) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def curve_tables(g: dict, datasets, viewspaces, n_views: int, what: str) -> list[str]:
    lines = []
    for d in datasets:
        for vs in viewspaces:
            rows = [
                [m] + [fmt(v) for v in s[what]]
                for (dd, vv, m, _), s in sorted(g.items(), key=lambda kv: method_rank(kv[0][2]))
                if dd == d and vv == vs
            ]
            if rows:
                lines += [f"\n**{d}, {vs} viewspace**\n"]
                lines += md_table(["method"] + [str(i + 1) for i in range(n_views)], rows)
    return lines


def category_tables(records, datasets, viewspaces) -> list[str]:
    lines = []
    for d in datasets:
        for vs in viewspaces:
            rs = [r for r in records if r.check is None and r.dataset == d and r.viewspace == vs]
            if not rs:
                continue
            methods = order_methods(r.method for r in rs)
            # A mesh folder has one category for all, the scans a few: their models are the rows.
            by_key = d in ("meshes", "scans")
            group = sorted({r.key if by_key else r.category for r in rs}, key=str)
            cell: dict[tuple, list[float]] = defaultdict(list)
            for r in rs:
                cell[(r.key if by_key else r.category, r.method)].append(r.auc)
            rows = [
                [c] + [fmt(np.mean(cell[(c, m)])) if cell[(c, m)] else "" for m in methods]
                for c in group
            ]
            lines += [f"\n**{d}, {vs} viewspace** (AUC)\n"]
            lines += md_table(["model" if by_key else "category"] + methods, rows)
    return lines


def method_table(methods, datasets, viewspaces, cell) -> list[str]:
    """A Markdown table of one row per method and one column per (dataset, viewspace); ``cell(
    method, dataset, viewspace)`` gives each cell's text ("" for none)."""
    header = ["method"] + [f"{d} / {vs}" for d in datasets for vs in viewspaces]
    rows = [[m] + [cell(m, d, vs) for d in datasets for vs in viewspaces] for m in methods]
    return md_table(header, rows)
