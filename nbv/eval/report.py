"""The report of an evaluation, ``report.md``, and :func:`write_outputs`, which writes it beside
``results.json`` and ``summary.csv`` (:mod:`nbv.eval.results_files`).

* ``report.md``: the tables (AUC, coverage and VIG by view, the VIG methods' VIG-AUC minus
  random's, AUC per category, the field's metrics with paired intervals, spread's ties,
  convex-hull replanning, disturbance checks, timing beside the paper's Table 1 and per
  decision), the paper's claims with the measured numbers, and what the run had to work
  around."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

from nbv.assets.weights import is_shipped
from nbv.eval.claims import claims
from nbv.eval.disturb import auc_changes
from nbv.eval.metric_tables import (
    decision_table,
    metrics_tables,
    tie_lines,
)
from nbv.eval.results_files import write_csv, write_json
from nbv.eval.statistics import (
    method_rank,
    order_methods,
    paired_from_means,
    run_statistics,
)
from nbv.eval.tables import category_tables, curve_tables, fmt, method_table
from nbv.eval.timing import COLUMNS, PAPER_TIMES, paper_ratios, timing_table
from nbv.policies.registry import (
    HULL_SCO,
    HULL_SCO_REPLAN,
    METHODS,
    RANDOM,
    SCORED,
    SPREAD,
    networks_of,
)
from nbv.utils.atomic import write_text
from nbv.utils.markdown import md_table
from nbv.utils.stats import N_BOOT, Interval


def verdict_of(diff: Interval, better: str, other: str) -> str:
    """What a paired interval (better - other) says: who is better, or that it cannot tell."""
    if diff.above_zero:
        return f"{better} better"
    if diff.below_zero:
        return f"{other} better"
    return "no difference shown (the interval holds 0)"


def _minus_base(means, base: str, others, datasets, viewspaces, seed: int, what: str):
    """The method table of ``what`` (an :class:`~nbv.eval.statistics.EpisodeMean` value) of each of
    ``others`` minus ``base``'s, paired over the same episodes: mean [95 % interval] cells."""

    def cell(m: str, d: str, vs: str) -> str:
        diff = paired_from_means(means, (d, vs, base, None), (d, vs, m, None), seed, what)
        return diff.interval.text(3) if diff else ""

    return method_table(others, datasets, viewspaces, cell)


def baseline_tables(means: dict, methods, datasets, viewspaces, seed: int) -> list[str]:
    """Every method minus spread and minus random, paired over the same episodes (``means``:
    :func:`~nbv.eval.statistics.episode_means` of the undisturbed episodes)."""
    lines = []
    for base in (SPREAD.name, RANDOM.name):
        others = [m for m in methods if m != base]
        if base in methods and others:
            lines += [
                "",
                f"## AUC minus {base}, paired over the same episodes",
                "",
                f"Mean [95 % bootstrap interval] of AUC(method) - AUC({base}) per episode. A "
                "method is better only when the whole interval lies above 0.",
                "",
            ]
            lines += _minus_base(means, base, others, datasets, viewspaces, seed, "auc")
    return lines


def vig_table(means: dict, methods, datasets, viewspaces, seed: int) -> list[str]:
    """The AUC of the VIG curve of every method made to raise VIG (the registry's ``score``),
    minus random's, paired over the same episodes; [] without random or such a method."""
    vig = [m for m in methods if m in METHODS and METHODS[m].score == "vig"]
    if RANDOM.name not in methods or not vig:
        return []
    return [
        "",
        f"## VIG-AUC minus {RANDOM.name}, paired over the same episodes",
        "",
        "VIG-AUC is coverage's AUC formula applied to the VIG curve (the paper's Fig. 13 as one "
        f"number). Mean [95 % bootstrap interval] of VIG-AUC(method) - VIG-AUC({RANDOM.name}) "
        "per episode, for the methods made to raise VIG (trained on it, greedy by it, or led "
        "by a network trained on it); episodes whose VIG is undefined are left out.",
        "",
        *_minus_base(means, RANDOM.name, vig, datasets, viewspaces, seed, "vig_auc"),
    ]


def filler_table(g: dict, methods, datasets, viewspaces) -> list[str]:
    """Mean zero-gain picks per planner episode: picks the fill rule made, not the score."""
    planners = [m for m in methods if m in METHODS and METHODS[m].geometric]
    if not planners:
        return []

    def cell(m: str, d: str, vs: str) -> str:
        c = g.get((d, vs, m, None))
        return f"{c['zero_gain']:.2f} of {c['planned']:.2f}" if c else ""

    return [
        "",
        "## Filler picks of the planners",
        "",
        "Mean picks per episode that newly cover no hull sample (zero gain), of the picks the "
        "planner made: the set cover was complete, and the greedy's spread-out fill (the "
        "spread rule) chose them, not the planner's score. hull_sco_probes' random probes are "
        "not planner picks.",
        "",
        *method_table(planners, datasets, viewspaces, cell),
    ]


def noise_table(changes: list[dict], sigmas) -> list[str]:
    """AUC change per position-noise sigma and method (paired, with intervals)."""
    rows = [r for r in changes if r["sigma"] is not None]
    if not rows:
        return []
    by = {(r["method"], r["dataset"], r["viewspace"], r["sigma"]): r for r in rows}
    keys = sorted({k[:3] for k in by}, key=lambda k: (k[1], k[2], method_rank(k[0])))
    table = []
    for method, dataset, vs in keys:
        first = next(by[(method, dataset, vs, x)] for x in sigmas if (method, dataset, vs, x) in by)
        table.append([method, dataset, vs, str(first["n"]), fmt(first["auc"])] + [
            by[(method, dataset, vs, x)]["change"].text(3) if (method, dataset, vs, x) in by
            else "" for x in sigmas
        ])  # fmt: skip
    return [
        "",
        "## Position noise on the cloud a method sees",
        "",
        "AUC change (noisy - clean, paired over the same episodes, mean [95 % bootstrap "
        "interval]) when every captured point the method sees is moved by isotropic Gaussian "
        "noise of standard deviation sigma (object frame: the object fits in radius 0.5). "
        "Coverage is scored on the true views.",
        "",
        *md_table(
            ["method", "dataset", "viewspace", "episodes", "AUC clean"]
            + [f"sigma {x:g}" for x in sigmas],
            table,
        ),  # fmt: skip
    ]


def _header(evaluation, methods: list[str]) -> list[str]:
    """The report's title, the episodes' protocol, the datasets (and what was left out of them),
    the networks and scorer used and the skipped methods."""
    s = evaluation.settings
    resumed = (
        f" ({evaluation.resumed} of them read back from `episodes.jsonl`)"
        if evaluation.resumed
        else ""
    )
    lines = [
        f"# Evaluation `{s.out_dir.name}`",
        "",
        f"{len(evaluation.records)} episodes{resumed}, run in {evaluation.seconds:.1f} s. Each "
        f"episode: a start view ({', '.join(map(str, s.start_views))}), then {s.n_views - 1} "
        f"views chosen by the method; coverage (eps from the dataset) and VIG after each view "
        f"against the ground truth; AUC = (c_1 + ... + c_{s.n_views - 1} + 0.5 "
        f"c_{s.n_views}) / {s.n_views}. Seed {s.seed}.",
        "",
        "Datasets:",
    ]
    for info in evaluation.datasets:
        lines.append(f"- `{info.name}`: {len(info.keys)} models from `{info.path}`")
        if info.failures:
            lines.append("  - not produced: " + "; ".join(f"{k} ({r})" for k, r in info.failures))
        if info.qhull_failures:
            lines.append(
                "  - Qhull failed on the ground truth (VIG unknown: NaN, left out of the VIG "
                "means; not a flat object): "
                + "; ".join(f"{k} ({msg})" for k, msg in info.qhull_failures)
            )
        if info.excluded:
            lines.append(
                "  - left out (their episodes chose a network checkpoint): "
                + "; ".join(f"{k} ({r})" for k, r in info.excluded)
            )
        if info.flat:
            lines.append(
                f"  - flat ground truth (no hull volume, VIG undefined: NaN, left out of the VIG "
                f"means): {', '.join(info.flat)}"
            )
    nets = [m for m in s.checkpoints if m in networks_of(methods)]
    if nets:
        lines += ["", "Networks: " + "; ".join(
            f"`{m}` from `{s.checkpoints[m]}`"
            + (" (the weights the package ships: no local training run)"
               if is_shipped(s.checkpoints[m]) else "")
            for m in nets
        )]  # fmt: skip
    scored = [m for m in methods if m in SCORED]
    if scored:
        scorer = s.scorer_file()
        lines += [
            "",
            "Learned score: " + ", ".join(f"`{m}`" for m in scored) + f" from `{scorer}`"
            + (" (the weights the package ships)" if is_shipped(scorer) else ""),
        ]  # fmt: skip
    if evaluation.skipped:
        lines += ["", "Skipped methods:"]
        lines += [f"- `{m}`: {reason}" for m, reason in evaluation.skipped.items()]
    return lines


def _replan_section(means: dict, methods: list[str], datasets: list[str],
                    viewspaces: list[str], seed: int) -> list[str]:  # fmt: skip
    """Replanning minus one-shot set cover, paired, when both ran ([] otherwise)."""
    if not {HULL_SCO.name, HULL_SCO_REPLAN.name} <= set(methods):
        return []
    lines = ["", "## Replanning after every view vs one-shot convex-hull set cover", ""]
    rows = []
    for d in datasets:
        for vs in viewspaces:
            diff = paired_from_means(
                means, (d, vs, HULL_SCO.name, None), (d, vs, HULL_SCO_REPLAN.name, None), seed
            )
            if diff:
                rows.append([d, vs, str(diff.interval.n), diff.interval.text(4),
                             verdict_of(diff.interval, "replan", "one-shot")])  # fmt: skip
    return lines + md_table(["dataset", "viewspace", "episodes", "AUC replan - one-shot", ""], rows)


def _disturbance_sections(records: list, s) -> list[str]:
    """The position-noise table and the disturbance checks (the paper's Fig. 18)."""
    changes = auc_changes(records, s.seed)
    lines = noise_table(changes, s.disturb.noise)
    changes = [r for r in changes if r["sigma"] is None]
    lines += ["", "## Disturbance checks (the paper's Fig. 18)", ""]
    if not changes:
        return lines + ["No check ran (disabled, or none of its methods ran)."]
    lines += [
        "AUC of the method, with the disturbance, and the paired change (disturbed - "
        "undisturbed, mean [95 % bootstrap interval] over the same episodes).",
        "",
    ]
    rows = [
        [r["check"], r["method"], r["dataset"], r["viewspace"], str(r["n"]), fmt(r["auc"]),
         fmt(r["auc_disturbed"]), r["change"].text(3)]
        for r in sorted(changes, key=lambda r: (r["dataset"], r["check"], r["method"]))
    ]  # fmt: skip
    return lines + md_table(
        ["check", "method", "dataset", "viewspace", "episodes", "AUC", "AUC disturbed", "change"],
        rows,
    )


def _timing_section(records: list, stats, methods: list[str], n_views: int) -> list[str]:
    """Seconds per episode and stage (the paper's Table 1), beside the paper's, and per
    decision."""
    times = timing_table(records)
    lines = [
        "",
        "## Timing per reconstruction (the paper's Table 1)",
        "",
        f"Mean seconds per episode ({n_views - 1} views after the start view) over all "
        "undisturbed episodes. `online` = total without the view simulation (the paper counts "
        "its Blender view simulation as offline; ours is analytic and included in `total`). "
        "Our PCNBV samples the stored clouds (up to the dataset's points_per_view a view), "
        "the paper's the full-resolution clouds.",
        "",
    ]
    cols = [c for c in COLUMNS if any(times[m][c] > 0 for m in times) or c in ("total", "online")]
    rows = [[m, str(times[m]["episodes"])] + [fmt(times[m][c], 4) for c in cols] for m in methods]
    lines += md_table(["method", "episodes", *cols], rows)
    ratios = paper_ratios(times)
    if ratios:
        lines += ["", "Paper's Table 1 beside ours (paper s / our s; above 1: we are faster):", ""]
        rows = []
        for m, r in ratios.items():
            for c, ratio in r.items():
                rows.append([m, c, fmt(PAPER_TIMES[m][c], 2), fmt(times[m][c], 4), fmt(ratio, 1)])
        lines += md_table(["method", "stage", "paper s", "our s", "paper / ours"], rows)
    return lines + decision_table(stats, methods)


def _notes_section(records: list) -> list[str]:
    """The work-arounds the methods noted, per method ([] without any)."""
    notes: dict[str, set] = defaultdict(set)
    for r in records:
        for n in r.notes:
            notes[f"{r.method}{'/' + r.check if r.check else ''}"].add(f"{r.key}: {n}")
    if not notes:
        return []
    return ["", "## Work-arounds", ""] + [
        f"- `{m}`: " + "; ".join(sorted(ns)) for m, ns in sorted(notes.items())
    ]


def report_body(evaluation) -> str:
    """The text of ``report.md`` but its plots (the costly part: every table)."""
    s = evaluation.settings
    records = evaluation.records
    stats = run_statistics(records, s.n_views)
    g = stats.groups
    datasets = [info.name for info in evaluation.datasets]
    viewspaces = list(s.viewspaces)
    methods = order_methods(r.method for r in records if r.check is None)
    lines = _header(evaluation, methods)
    lines += [
        "",
        "## AUC (mean [95 % bootstrap interval] over models x start views)",
        "",
        f"Intervals resample models (seed {s.seed}, {N_BOOT:,} draws). Random is averaged over "
        f"{s.random_repeats} seeds per episode first.",
        "",
    ]
    lines += method_table(
        methods, datasets, viewspaces,
        lambda m, d, vs: g[(d, vs, m, None)]["auc_ci"].text(3, signed=False)
        if (d, vs, m, None) in g else "",
    )  # fmt: skip
    lines += baseline_tables(stats.means, methods, datasets, viewspaces, s.seed)
    lines += filler_table(g, methods, datasets, viewspaces)
    lines += tie_lines(stats, datasets, viewspaces)
    lines += metrics_tables(stats, datasets, viewspaces, s.n_views, s.seed)
    lines += ["", "## Mean coverage after each view", ""]
    lines += curve_tables(g, datasets, viewspaces, s.n_views, "coverage")
    lines += [
        "",
        "## Mean VIG after each view",
        "",
        "VIG = hull volume of the views' points / hull volume of the ground-truth samples; it "
        "can pass 1 a little, since the samples' hull lies slightly inside the surface the "
        "views capture. Models with a flat ground truth are left out (their VIG is undefined).",
    ]
    lines += curve_tables(g, datasets, viewspaces, s.n_views, "vig")
    lines += vig_table(stats.means, methods, datasets, viewspaces, s.seed)
    lines += ["", "## AUC per category", ""]
    lines += category_tables(records, datasets, viewspaces)
    lines += _replan_section(stats.means, methods, datasets, viewspaces, s.seed)
    lines += _disturbance_sections(records, s)
    lines += _timing_section(records, stats, methods, s.n_views)
    lines += ["", "## The paper's claims, measured", ""]
    lines += claims(evaluation)
    lines += _notes_section(records)
    return "\n".join(lines) + "\n"


def plots_section(out_dir: Path) -> str:
    """The report's "Plots" section: the :data:`PLOT_FILES` in ``out_dir`` ("" for none)."""
    pngs = [p for p in PLOT_FILES if (out_dir / p).exists()]
    if not pngs:
        return ""
    return "\n".join(["", "## Plots", "", *(f"![{p}]({p})" for p in pngs)]) + "\n"


#: The PNG files :mod:`nbv.eval.plots` writes.
PLOT_FILES = (
    "coverage_by_view.png",
    "vig_by_view.png",
    "disturbance.png",
    "noise.png",
    "reconstruction.png",
    "metrics.png",
)


def write_outputs(evaluation, report_only: bool = False, body: str | None = None) -> str:
    """Write results.json, summary.csv and report.md into ``evaluation.settings.out_dir``
    (only report.md with ``report_only``).

    Args:
        evaluation: the run.
        report_only: write report.md alone.
        body: :func:`report_body` of ``evaluation`` when already computed (a second writing,
            after the plots, reuses the first's).

    Returns:
        The report's body, for a second writing.
    """
    out = Path(evaluation.settings.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if not report_only:
        write_json(evaluation, out / "results.json")
        write_csv(evaluation, out / "summary.csv")
    body = report_body(evaluation) if body is None else body
    write_text(out / "report.md", body + plots_section(out))
    return body
