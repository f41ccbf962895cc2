"""The evaluation's pictures (matplotlib, Agg), written beside report.md.

* ``coverage_by_view.png``: mean coverage after each view, one panel per dataset and viewspace
  (the paper's Fig. 15 and 17);
* ``vig_by_view.png``: mean VIG after each view (Fig. 13);
* ``disturbance.png``: AUC of each method with and without each disturbance (Fig. 18);
* ``metrics.png``: the field's metrics per method (final coverage, views to 90 % of the
  viewspace's coverage, Chamfer distance, F-score at 2 eps, camera path), one row of panels per
  dataset and viewspace;
* ``reconstruction.png``: one convex-hull set-cover episode: the start view's cloud, its hull and
  the chosen cameras, and the reconstruction after all views (Fig. 16).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 - the backend must be chosen first
import numpy as np  # noqa: E402

from nbv.eval.disturb import auc_changes  # noqa: E402
from nbv.eval.metrics import plot_panels  # noqa: E402
from nbv.eval.statistics import (  # noqa: E402
    episode_values,
    groups,
    method_rank,
    order_methods,
    summaries,
)
from nbv.policies.registry import GEOMETRIC, METHODS, ORACLE  # noqa: E402
from nbv.utils.atomic import save_figure

CHECK_LABELS = {
    "random_cloud": "random cloud",
    "permuted_state": "permuted view state",
    "random_hull": "hull of random points",
}


#: How each registered method is drawn, the same in every figure: matplotlib colour and line
#: style (a method missing here is drawn in :data:`UNSTYLED`).
STYLES: dict[str, tuple[str, str]] = {
    "random": ("#7f7f7f", ":"),
    "spread": ("#bcbd22", ":"),
    "oracle": ("#000000", "--"),
    "oracle_vig": ("#525252", "--"),
    "pcnbv": ("#1f77b4", "-"),
    "pcnbv_sph": ("#17becf", "-"),
    "pcnbv_vig": ("#aec7e8", "-."),
    "pcnbv_sph_vig": ("#9edae5", "-."),
    "pcnbv_matched": ("#08519c", ":"),
    "pcnbv_sph_matched": ("#0f7c86", ":"),
    "vcnbv": ("#393b79", "-"),
    "vcnbv_map": ("#6b6ecf", "--"),
    "hull_sco": ("#d62728", "-"),
    "hull_sco_sph": ("#ff7f0e", "-"),
    "hull_sco_probes": ("#9467bd", "-."),
    "hull_sco_replan": ("#2ca02c", "-."),
    "vig_hull_sco": ("#ff9896", "--"),
    "vig_hull_sco_matched": ("#ad494a", "--"),
    "vig_hull_sco_sph": ("#ffbb78", "--"),
    "ig": ("#e377c2", "-"),
    "hull_ig": ("#8c564b", "-"),
    "ig_learned": ("#c51b7d", "--"),
    "ig_area_factor": ("#e7969c", "-."),
    "ig_proximity": ("#7b4173", ":"),
    "completion_hull_sco": ("#7f2704", "-"),
    "completion_hull_sco_replan": ("#a63603", "-."),
    "completion_gain": ("#006d2c", "-"),
    "completion_gain_authors": ("#74c476", "--"),
}
#: The colour and line style of a method :data:`STYLES` does not name.
UNSTYLED = ("#8c564b", "-")


def _style(method: str) -> tuple[str, str]:
    """The method's colour and line style (:data:`STYLES`; the same in every figure)."""
    return STYLES.get(method, UNSTYLED)


def curves_figure(evaluation, what: str, path: Path) -> None:
    """Mean ``what`` (``coverage`` or ``vig``) after each view: datasets x viewspaces panels.

    Coverage legends carry each method's AUC. VIG may pass 1 a little: the ground truth's hull
    is that of its surface samples, slightly inside the true surface the views capture.
    """
    g = groups(evaluation.records)
    datasets = [info.name for info in evaluation.datasets]
    viewspaces = list(evaluation.settings.viewspaces)
    n = evaluation.settings.n_views
    fig, axes = plt.subplots(
        len(datasets), len(viewspaces), figsize=(5.2 * len(viewspaces), 3.9 * len(datasets)),
        squeeze=False, sharey=True,
    )  # fmt: skip
    x = np.arange(1, n + 1)
    for i, d in enumerate(datasets):
        for j, vs in enumerate(viewspaces):
            ax = axes[i, j]
            for m in order_methods(key[2] for key in g if key[0] == d and key[1] == vs):
                s = g[(d, vs, m, None)]
                colour, line = _style(m)
                label = f"{m} (AUC {s['auc']:.3f})" if what == "coverage" else m
                ax.plot(x, s[what], line, color=colour, marker="o", ms=3, lw=1.6, label=label)
            if what == "vig":
                ax.axhline(1.0, color="#999999", lw=0.8)
            ax.set_title(f"{d}, {vs} viewspace", fontsize=10)
            ax.set_xticks(x)
            ax.set_xlabel("views captured")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="lower right")
            if j == 0:
                ax.set_ylabel(f"mean {what.upper() if what == 'vig' else what}")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def disturbance_figure(evaluation, path: Path) -> bool:
    """AUC of each checked method with and without each disturbance; False if none ran."""
    rows = [r for r in auc_changes(evaluation.records) if r["sigma"] is None]
    if not rows:
        return False
    panels = sorted({(r["dataset"], r["viewspace"]) for r in rows})
    fig, axes = plt.subplots(1, len(panels), figsize=(6.5 * len(panels), 4.6), squeeze=False)
    for ax, (d, vs) in zip(axes[0], panels, strict=True):
        rs = sorted(
            (r for r in rows if r["dataset"] == d and r["viewspace"] == vs),
            key=lambda r: (method_rank(r["method"]), r["check"]),
        )
        labels, plain, disturbed, colours = [], [], [], []
        for r in rs:
            labels.append(f"{r['method']}\n{CHECK_LABELS.get(r['check'], r['check'])}")
            plain.append(r["auc"])
            disturbed.append(r["auc_disturbed"])
            colours.append(_style(r["method"])[0])
        y = np.arange(len(rs))
        ax.barh(y + 0.2, plain, 0.38, color=colours, alpha=0.35, label="undisturbed")
        ax.barh(y - 0.2, disturbed, 0.38, color=colours, label="disturbed")
        for yi, (p, q) in enumerate(zip(plain, disturbed, strict=True)):
            ax.text(q, yi - 0.2, f" {q - p:+.3f}", va="center", fontsize=8)
        ax.set_yticks(y, labels, fontsize=8)
        ax.invert_yaxis()
        ax.set_xlabel("AUC")
        ax.set_xlim(0, max(plain + disturbed) * 1.18)
        ax.set_title(f"{d}, {vs} viewspace: AUC change", fontsize=10)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2)
        ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def noise_figure(evaluation, path: Path) -> bool:
    """AUC change against the position noise's sigma, per method, with the paired intervals;
    False if the check did not run."""
    rows = [r for r in auc_changes(evaluation.records) if r["sigma"] is not None]
    if not rows:
        return False
    panels = sorted({(r["dataset"], r["viewspace"]) for r in rows})
    fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 4.2), squeeze=False)
    for ax, (d, vs) in zip(axes[0], panels, strict=True):
        here = [r for r in rows if r["dataset"] == d and r["viewspace"] == vs]
        for m in sorted({r["method"] for r in here}, key=method_rank):
            rs = sorted((r for r in here if r["method"] == m), key=lambda r: r["sigma"])
            x = np.array([r["sigma"] for r in rs])
            y = np.array([r["change"].mean for r in rs])
            err = np.array([[r["change"].mean - r["change"].low for r in rs],
                            [r["change"].high - r["change"].mean for r in rs]])  # fmt: skip
            colour, line = _style(m)
            ax.errorbar(x, y, yerr=np.nan_to_num(err), color=colour, ls=line, marker="o",
                        capsize=3, label=m)  # fmt: skip
        ax.axhline(0.0, color="#999999", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("position noise sigma (object radius 0.5)")
        ax.set_ylabel("AUC change (noisy - clean), 95 % interval")
        ax.set_title(f"{d}, {vs} viewspace", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def metrics_figure(evaluation, path: Path) -> bool:
    """Horizontal bars of each method's mean metrics, a row of panels per dataset and viewspace;
    False when no record has metrics."""
    n = evaluation.settings.n_views
    summary = summaries(episode_values([r for r in evaluation.records if r.check is None], n))
    rows = sorted({k[:2] for k in summary})
    if not rows:
        return False
    panels = plot_panels()
    size = (3.3 * len(panels), 0.8 + 0.22 * len(METHODS) * len(rows))
    fig, axes = plt.subplots(len(rows), len(panels), figsize=size, squeeze=False)
    for i, (d, vs) in enumerate(rows):
        methods = order_methods(k[2] for k in summary if k[:2] == (d, vs))
        y = np.arange(len(methods))
        for j, (key, title) in enumerate(panels):
            ax = axes[i, j]
            values = [summary[(d, vs, m, None)][key] for m in methods]
            ax.barh(y, np.nan_to_num(values), color=[_style(m)[0] for m in methods])
            ax.set_yticks(y, methods if j == 0 else [""] * len(methods), fontsize=7)
            ax.invert_yaxis()
            ax.tick_params(axis="x", labelsize=7)
            ax.grid(axis="x", alpha=0.3)
            ax.set_title(f"{title}\n{d}, {vs}" if i == 0 else f"{d}, {vs}", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def _example(evaluation):
    """The episode drawn in reconstruction.png: the first convex-hull (else any) episode."""
    for method in (*GEOMETRIC, ORACLE.name):
        for r in evaluation.records:
            if r.method == method and r.check is None:
                return r
    return next((r for r in evaluation.records if r.check is None), None)


def _hull_faces(points: np.ndarray):
    from scipy.spatial import ConvexHull, QhullError

    try:
        return ConvexHull(points).simplices
    except (QhullError, ValueError):
        return None


def reconstruction_figure(evaluation, path: Path) -> bool:
    """One episode in 3D: the start view's cloud with its hull and the chosen cameras (left),
    the ground truth and what the views captured (right). False when nothing ran."""
    import nbv.dataset
    from nbv.eval.prepare import read_model

    r = _example(evaluation)
    if r is None:
        return False
    info = next(i for i in evaluation.datasets if i.name == r.dataset)
    model = read_model(nbv.dataset.open(info.path), info.rendered, r.key, (r.viewspace,))
    view = model.views[r.viewspace]
    cams = view.poses[:, :3, 3]
    start = view.view_points(r.views[0])
    captured = np.concatenate([view.view_points(v) for v in r.views])
    fig = plt.figure(figsize=(12, 6.2))
    for k, title in enumerate(
        (
            f"{r.method}: start view {r.views[0]}, its cloud and hull, chosen cameras",
            f"after {len(r.views)} views: coverage {r.coverage[-1]:.3f}",
        )
    ):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        # The world is Y-up: draw (x, z, y) so that up is up on the page.
        ax.scatter(cams[:, 0], cams[:, 2], cams[:, 1], s=8, color="#bbbbbb", depthshade=False)
        for order, v in enumerate(r.views):
            c = cams[v]
            colour = "#d62728" if order == 0 else "#1f77b4"
            ax.scatter(c[0], c[2], c[1], s=30, color=colour, depthshade=False)
            ax.plot([c[0], 0.6 * c[0]], [c[2], 0.6 * c[2]], [c[1], 0.6 * c[1]], color=colour, lw=1)
            ax.text(c[0] * 1.08, c[2] * 1.08, c[1] * 1.08, str(order), fontsize=7, color=colour)
        if k == 0:
            sub = start[:: max(1, len(start) // 1500)]
            ax.scatter(sub[:, 0], sub[:, 2], sub[:, 1], s=1, color="#d62728", alpha=0.6)
            faces = _hull_faces(start.astype(np.float64))
            if faces is not None:
                ax.plot_trisurf(
                    start[:, 0], start[:, 2], start[:, 1], triangles=faces,
                    color="#ff7f0e", alpha=0.18, edgecolor="#ff7f0e", linewidth=0.2,
                )  # fmt: skip
        else:
            gt = model.gt_points[:: max(1, len(model.gt_points) // 3000)]
            ax.scatter(gt[:, 0], gt[:, 2], gt[:, 1], s=1, color="#bbbbbb", alpha=0.4)
            sub = captured[:: max(1, len(captured) // 4000)]
            ax.scatter(sub[:, 0], sub[:, 2], sub[:, 1], s=1, color="#1f77b4", alpha=0.7)
        ax.set_title(title, fontsize=9)
        ax.set_box_aspect((1, 1, 1), zoom=1.05)
        for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
            setter(-1.05, 1.05)
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            axis.set_pane_color((1, 1, 1, 0))
        ax.set_xlabel("x", fontsize=7)
        ax.set_ylabel("z", fontsize=7)
        ax.set_zlabel("y (up)", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.view_init(elev=22, azim=-60)
    fig.suptitle(
        f"{r.dataset} model {r.key} ({r.category}), {r.viewspace} viewspace; "
        "red: start camera, blue: chosen cameras in order",
        fontsize=9,
    )
    fig.subplots_adjust(left=0.0, right=0.97, bottom=0.03, top=0.9, wspace=0.05)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def draw_all(evaluation) -> list[Path]:
    """Draw every figure into ``evaluation.settings.out_dir``; returns the files written."""
    out = Path(evaluation.settings.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if evaluation.records:
        for what in ("coverage", "vig"):
            curves_figure(evaluation, what, out / f"{what}_by_view.png")
            written.append(out / f"{what}_by_view.png")
    if disturbance_figure(evaluation, out / "disturbance.png"):
        written.append(out / "disturbance.png")
    if noise_figure(evaluation, out / "noise.png"):
        written.append(out / "noise.png")
    if metrics_figure(evaluation, out / "metrics.png"):
        written.append(out / "metrics.png")
    if reconstruction_figure(evaluation, out / "reconstruction.png"):
        written.append(out / "reconstruction.png")
    return written
