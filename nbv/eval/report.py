"""The outputs of an evaluation: ``results.json``, ``summary.csv`` and ``report.md``.

* ``results.json``: the settings, the skipped methods, the datasets, and every episode
  (:class:`nbv.eval.protocol.EpisodeRecord`; undefined VIG is ``null``).
* ``summary.csv``: one row per (dataset, viewspace, method, check): episodes, mean AUC and its
  standard error, mean coverage and VIG after each view, mean seconds per reconstruction.
* ``report.md``: the tables (AUC, coverage and VIG by view, AUC per category, convex-hull
  replanning, disturbance checks, timing beside the paper's Table 1), the paper's claims with
  the measured numbers, and what the run had to work around.
"""

from __future__ import annotations

import csv
import io
import json
from collections import defaultdict
from dataclasses import asdict
from pathlib import Path

import numpy as np

from nbv.eval.disturb import auc_changes
from nbv.eval.timing import COLUMNS, PAPER_TIMES, paper_ratios, timing_table
from nbv.policies.registry import (
    HULL_SCO,
    HULL_SCO_REPLAN,
    METHODS,
    PCNBV,
    PCNBV_SPH,
    RANDOM,
)
from nbv.utils.atomic import write_text

#: Paper-claim thresholds (stated in the report).
CLOSE_AUC = 0.02
DEGRADE_FRACTION = 0.5
HOLD_FRACTION = 0.8


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


def _f(x: float, digits: int = 3) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(row) + " |" for row in rows]


def write_json(evaluation, path: Path) -> None:
    """``results.json``: settings, skipped methods, datasets, seconds, every episode."""
    data = {
        "settings": _jsonable(asdict(evaluation.settings)),
        "skipped": evaluation.skipped,
        "datasets": [_jsonable(asdict(d)) for d in evaluation.datasets],
        "seconds": evaluation.seconds,
        "resumed_episodes": evaluation.resumed,
        "episodes": [_jsonable(r.to_json()) for r in evaluation.records],
    }
    write_text(path, json.dumps(data, indent=1, allow_nan=False))


def write_csv(evaluation, path: Path) -> None:
    """``summary.csv``: one row per (dataset, viewspace, method, check)."""
    g = groups(evaluation.records, check=True)
    n_views = evaluation.settings.n_views
    header = ["dataset", "viewspace", "method", "check", "episodes", "auc", "auc_se"]
    header += [f"coverage_{i + 1}" for i in range(n_views)]
    header += [f"vig_{i + 1}" for i in range(n_views)]
    header += ["seconds_total", "seconds_online"]
    handle = io.StringIO()
    writer = csv.writer(handle, lineterminator="\n")
    writer.writerow(header)
    for (dataset, vs, method, check), s in sorted(
        g.items(), key=lambda kv: (kv[0][0], kv[0][1], method_rank(kv[0][2]), kv[0][3] or "")
    ):
        row = [dataset, vs, method, check or "", s["n"], f"{s['auc']:.6f}"]
        row.append("" if not np.isfinite(s["auc_se"]) else f"{s['auc_se']:.6f}")
        row += [f"{c:.6f}" for c in s["coverage"]]
        row += ["" if not np.isfinite(v) else f"{v:.6f}" for v in s["vig"]]
        row += [f"{s['total']:.6f}", f"{s['online']:.6f}"]
        writer.writerow(row)
    write_text(path, handle.getvalue())


def _curve_tables(g: dict, datasets, viewspaces, n_views: int, what: str) -> list[str]:
    lines = []
    for d in datasets:
        for vs in viewspaces:
            rows = [
                [m] + [_f(v) for v in s[what]]
                for (dd, vv, m, _), s in sorted(g.items(), key=lambda kv: method_rank(kv[0][2]))
                if dd == d and vv == vs
            ]
            if rows:
                lines += [f"\n**{d}, {vs} viewspace**\n"]
                lines += _table(["method"] + [str(i + 1) for i in range(n_views)], rows)
    return lines


def _category_tables(records, datasets, viewspaces) -> list[str]:
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
                [c] + [_f(np.mean(cell[(c, m)])) if cell[(c, m)] else "" for m in methods]
                for c in group
            ]
            lines += [f"\n**{d}, {vs} viewspace** (AUC)\n"]
            lines += _table(["model" if by_key else "category"] + methods, rows)
    return lines


def _paired(records, a: str, b: str, dataset: str, viewspace: str) -> tuple[float, float, int]:
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


def _verdict(ok: bool | None) -> str:
    return "n/a (not measured)" if ok is None else ("**holds**" if ok else "**does not hold**")


def _yes(ok: bool) -> str:
    return "yes" if ok else "no"


def _dataset_claims(d: str, g: dict, times: dict, changes: list[dict]) -> list[str]:
    """The four claims on dataset ``d`` (see :func:`claims`)."""

    def auc(vs: str, m: str) -> float:
        s = g.get((d, vs, m, None))
        return s["auc"] if s else float("nan")

    def gain(vs: str, m: str) -> float:
        return auc(vs, m) - auc(vs, RANDOM.name)

    lines = []
    rnd = auc("original", RANDOM.name)
    beat = [m for m in (PCNBV.name, PCNBV_SPH.name, HULL_SCO.name) if (d, "original", m, None) in g]
    if beat and np.isfinite(rnd):
        ok = all(auc("original", m) > rnd for m in beat)
        nums = ", ".join(f"{m} {_f(auc('original', m))}" for m in beat)
        lines.append(
            f"1. *Networks and convex-hull planner beat random* (AUC, original viewspace): "
            f"{nums} vs random {_f(rnd)}: {_verdict(ok)}."
        )
    else:
        lines.append(f"1. *Networks and convex-hull planner beat random*: {_verdict(None)}.")

    nets = [m for m in (PCNBV.name, PCNBV_SPH.name) if (d, "permuted", m, None) in g]
    needed = [(d, vs, m, None) for vs in ("original", "permuted") for m in (HULL_SCO.name, RANDOM.name)]
    if nets and all(k in g for k in needed):
        net_ok = all(gain("permuted", m) < DEGRADE_FRACTION * gain("original", m) for m in nets)
        hull_ok = gain("permuted", HULL_SCO.name) >= HOLD_FRACTION * gain("original", HULL_SCO.name)
        nums = "; ".join(
            f"{m} {_f(gain('original', m))} -> {_f(gain('permuted', m))}"
            for m in [*nets, HULL_SCO.name]
        )
        lines.append(
            "2. *On the permuted viewspace the networks degrade while the convex-hull planner "
            f"holds* (AUC above random, original -> permuted: {nums}; criterion: each network "
            f"keeps less than {DEGRADE_FRACTION:.0%} of its advantage, the planner at least "
            f"{HOLD_FRACTION:.0%}): {_verdict(net_ok and hull_ok)} (networks degrade: "
            f"{_yes(net_ok)}; planner holds: {_yes(hull_ok)})."
        )
    else:
        lines.append(f"2. *Permuted viewspace*: {_verdict(None)}.")

    if (d, "original", PCNBV.name, None) in g and (d, "original", PCNBV_SPH.name, None) in g:
        diff = auc("original", PCNBV_SPH.name) - auc("original", PCNBV.name)
        t_p, t_s = times[PCNBV.name]["total"], times[PCNBV_SPH.name]["total"]
        close, faster = abs(diff) <= CLOSE_AUC, t_s < t_p
        lines.append(
            f"3. *PCNBV-sph is close to PCNBV in AUC and faster*: AUC "
            f"{_f(auc('original', PCNBV_SPH.name))} vs {_f(auc('original', PCNBV.name))} "
            f"(difference {diff:+.3f}; close = within {CLOSE_AUC}), {t_s:.3f} s vs {t_p:.3f} s "
            f"per reconstruction (all runs): {_verdict(close and faster)} (close: "
            f"{_yes(close)}; faster: {_yes(faster)})."
        )
    else:
        lines.append(f"3. *PCNBV-sph close to PCNBV and faster*: {_verdict(None)}.")

    parts, oks = [], []
    for m in (PCNBV.name, PCNBV_SPH.name):
        c = {
            row["check"]: row["change"]
            for row in changes
            if row["method"] == m and row["dataset"] == d and row["viewspace"] == "original"
        }
        if "random_cloud" in c and "permuted_state" in c:
            oks.append(c["permuted_state"] < c["random_cloud"])
            parts.append(
                f"{m}: permuted state {c['permuted_state']:+.3f}, random cloud "
                f"{c['random_cloud']:+.3f}"
            )
    if oks:
        lines.append(
            "4. *The networks lean on the view state more than on the cloud* (AUC change, "
            f"original viewspace; {'; '.join(parts)}; criterion: the permuted state costs more "
            f"than the random cloud): {_verdict(all(oks))}."
        )
    else:
        lines.append(f"4. *Networks lean on the view state*: {_verdict(None)}.")
    return lines


def claims(evaluation) -> list[str]:
    """The paper's qualitative claims, per dataset, each with the measured numbers, the
    criterion and a verdict."""
    g = groups(evaluation.records)
    times = timing_table(evaluation.records)
    changes = auc_changes(evaluation.records)
    lines = []
    for d in [info.name for info in evaluation.datasets]:
        lines += [f"\n### {d}\n", *_dataset_claims(d, g, times, changes)]
    return lines


def report_markdown(evaluation) -> str:
    """The text of ``report.md``."""
    s = evaluation.settings
    records = evaluation.records
    g = groups(records)
    datasets = [info.name for info in evaluation.datasets]
    viewspaces = list(s.viewspaces)
    methods = order_methods(r.method for r in records if r.check is None)
    n_eps = len(records)
    resumed = (
        f" ({evaluation.resumed} of them read back from `episodes.jsonl`)"
        if evaluation.resumed
        else ""
    )
    lines = [
        f"# Evaluation `{s.out_dir.name}`",
        "",
        f"{n_eps} episodes{resumed}, run in {evaluation.seconds:.1f} s. Each episode: a start view "
        f"({', '.join(map(str, s.start_views))}), then {s.n_views - 1} views chosen by the "
        f"method; coverage (eps from the dataset) and VIG after each view against the "
        f"ground truth; AUC = (c_1 + ... + c_{s.n_views - 1} + 0.5 c_{s.n_views}) / "
        f"{s.n_views}. Seed {s.seed}.",
        "",
        "Datasets:",
    ]
    for info in evaluation.datasets:
        lines.append(f"- `{info.name}`: {len(info.keys)} models from `{info.path}`")
        if info.failures:
            lines.append("  - not produced: " + "; ".join(f"{k} ({r})" for k, r in info.failures))
        if info.flat:
            lines.append(
                f"  - flat ground truth (no hull volume, VIG undefined: NaN, left out of the VIG "
                f"means): {', '.join(info.flat)}"
            )
    nets = [m for m in s.checkpoints if m in methods]
    if nets:
        lines += ["", "Networks: " + "; ".join(f"`{m}` from `{s.checkpoints[m]}`" for m in nets)]
    if evaluation.skipped:
        lines += ["", "Skipped methods:"]
        lines += [f"- `{m}`: {reason}" for m, reason in evaluation.skipped.items()]

    lines += ["", "## AUC (mean ± standard error over models x start views)", ""]
    header = ["method"] + [f"{d} / {vs}" for d in datasets for vs in viewspaces]
    rows = []
    for m in methods:
        row = [m]
        for d in datasets:
            for vs in viewspaces:
                c = g.get((d, vs, m, None))
                row.append(f"{_f(c['auc'])} ± {_f(c['auc_se'])}" if c else "")
        rows.append(row)
    lines += _table(header, rows)

    lines += ["", "## Mean coverage after each view", ""]
    lines += _curve_tables(g, datasets, viewspaces, s.n_views, "coverage")
    lines += [
        "",
        "## Mean VIG after each view",
        "",
        "VIG = hull volume of the views' points / hull volume of the ground-truth samples; it "
        "can pass 1 a little, since the samples' hull lies slightly inside the surface the "
        "views capture. Models with a flat ground truth are left out (their VIG is undefined).",
    ]
    lines += _curve_tables(g, datasets, viewspaces, s.n_views, "vig")
    lines += ["", "## AUC per category", ""]
    lines += _category_tables(records, datasets, viewspaces)

    if {HULL_SCO.name, HULL_SCO_REPLAN.name} <= set(methods):
        lines += ["", "## Replanning after every view vs one-shot convex-hull set cover", ""]
        rows = []
        for d in datasets:
            for vs in viewspaces:
                mean, se, n = _paired(records, HULL_SCO.name, HULL_SCO_REPLAN.name, d, vs)
                if n:
                    better = "replan better" if mean > 0 else "one-shot better or equal"
                    rows.append([d, vs, str(n), f"{mean:+.4f} ± {_f(se, 4)}", better])
        lines += _table(["dataset", "viewspace", "episodes", "AUC replan - one-shot", ""], rows)

    changes = auc_changes(records)
    lines += ["", "## Disturbance checks (the paper's Fig. 18)", ""]
    if changes:
        lines += [
            "AUC of the method, with the disturbance, and the paired change (disturbed - "
            "undisturbed, mean ± standard error over the same episodes).",
            "",
        ]
        rows = [
            [r["check"], r["method"], r["dataset"], r["viewspace"], str(r["n"]), _f(r["auc"]),
             _f(r["auc_disturbed"]), f"{r['change']:+.3f} ± {_f(r['change_se'])}"]
            for r in sorted(changes, key=lambda r: (r["dataset"], r["check"], r["method"]))
        ]  # fmt: skip
        lines += _table(
            ["check", "method", "dataset", "viewspace", "episodes", "AUC", "AUC disturbed",
             "change"], rows,
        )  # fmt: skip
    else:
        lines.append("No check ran (disabled, or none of its methods ran).")

    times = timing_table(records)
    lines += [
        "",
        "## Timing per reconstruction (the paper's Table 1)",
        "",
        f"Mean seconds per episode ({s.n_views - 1} views after the start view) over all "
        "undisturbed episodes. `online` = total without the view simulation (the paper counts "
        "its Blender view simulation as offline; ours is analytic and included in `total`). "
        "Our PCNBV samples the stored clouds (up to the dataset's points_per_view a view), "
        "the paper's the full-resolution clouds.",
        "",
    ]
    cols = [c for c in COLUMNS if any(times[m][c] > 0 for m in times) or c in ("total", "online")]
    rows = [[m, str(times[m]["episodes"])] + [_f(times[m][c], 4) for c in cols] for m in methods]
    lines += _table(["method", "episodes", *cols], rows)
    ratios = paper_ratios(times)
    if ratios:
        lines += ["", "Paper's Table 1 beside ours (paper s / our s; above 1: we are faster):", ""]
        rows = []
        for m, r in ratios.items():
            for c, ratio in r.items():
                rows.append([m, c, _f(PAPER_TIMES[m][c], 2), _f(times[m][c], 4), _f(ratio, 1)])
        lines += _table(["method", "stage", "paper s", "our s", "paper / ours"], rows)

    lines += ["", "## The paper's claims, measured", ""]
    lines += claims(evaluation)

    notes: dict[str, set] = defaultdict(set)
    for r in records:
        for n in r.notes:
            notes[f"{r.method}{'/' + r.check if r.check else ''}"].add(f"{r.key}: {n}")
    if notes:
        lines += ["", "## Work-arounds", ""]
        for m, ns in sorted(notes.items()):
            lines.append(f"- `{m}`: " + "; ".join(sorted(ns)))

    pngs = [p for p in PLOT_FILES if (Path(s.out_dir) / p).exists()]
    if pngs:
        lines += ["", "## Plots", ""]
        lines += [f"![{p}]({p})" for p in pngs]
    return "\n".join(lines) + "\n"


#: The PNG files :mod:`nbv.eval.plots` writes.
PLOT_FILES = ("coverage_by_view.png", "vig_by_view.png", "disturbance.png", "reconstruction.png")


def write_outputs(evaluation, report_only: bool = False) -> None:
    """Write results.json, summary.csv and report.md into ``evaluation.settings.out_dir``
    (only report.md with ``report_only``)."""
    out = Path(evaluation.settings.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if not report_only:
        write_json(evaluation, out / "results.json")
        write_csv(evaluation, out / "summary.csv")
    write_text(out / "report.md", report_markdown(evaluation))
