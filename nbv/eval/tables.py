"""Means over episodes and the Markdown tables of the report.

By method, by view, by category, and paired differences between two methods."""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from nbv.policies.registry import METHODS
from nbv.utils.markdown import md_table


def groups(records: list, check: bool = False) -> dict[tuple, dict]:
    """Means over episodes, by (dataset, viewspace, method, check).

    Args:
        records: episode records.
        check: keep the disturbance checks too (otherwise only the methods as they are).

    Returns:
        key -> ``n``, ``auc`` (mean), ``auc_se``, ``coverage`` and ``vig`` (mean curves; VIG
        averages the models where it is defined, NaN if none), ``total`` and ``online``
        (mean seconds per reconstruction).
    """
    by: dict[tuple, list] = defaultdict(list)
    for r in records:
        if r.check is None or check:
            by[(r.dataset, r.viewspace, r.method, r.check)].append(r)
    out = {}
    for key, rs in by.items():
        aucs = np.array([r.auc for r in rs])
        vig = np.array([r.vig for r in rs], dtype=float)
        defined = np.isfinite(vig).all(axis=1)
        out[key] = dict(
            n=len(rs),
            auc=float(aucs.mean()),
            auc_se=float(aucs.std(ddof=1) / np.sqrt(len(rs))) if len(rs) > 1 else float("nan"),
            coverage=np.mean([r.coverage for r in rs], axis=0),
            vig=vig[defined].mean(axis=0) if defined.any() else np.full(vig.shape[1], np.nan),
            total=float(np.mean([r.timings["total"] for r in rs])),
            online=float(np.mean([r.timings["online"] for r in rs])),
        )
    return out


def method_rank(method: str) -> int:
    """Position of a method in report order (the registry's; unknown names last)."""
    order = list(METHODS)
    return order.index(method) if method in order else len(order)


def order_methods(methods) -> list[str]:
    """Distinct method names in report order."""
    return sorted(set(methods), key=method_rank)


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
            # A mesh folder has one category for all; its models are the interesting rows.
            by_key = d == "meshes"
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


def paired_auc(records, a: str, b: str, dataset: str, viewspace: str) -> tuple[float, float, int]:
    """Mean and standard error of AUC(b) - AUC(a) over the episodes both ran."""
    auc = {
        (r.method, r.key, r.start): r.auc
        for r in records
        if r.check is None and r.dataset == dataset and r.viewspace == viewspace
    }
    diffs = [auc[(b, k, s)] - v for (m, k, s), v in auc.items() if m == a and (b, k, s) in auc]
    if not diffs:
        return float("nan"), float("nan"), 0
    d = np.array(diffs)
    se = float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else float("nan")
    return float(d.mean()), se, len(d)
