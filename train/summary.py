"""``python -m train.summary <sweep dir or runs dir> [--out DIR]``: the cross-validation table.

Finds every training run under the folder (a hydra sweep folder, whose jobs point at their run
folders through ``run.json``, or a folder of run folders such as ``outputs/train``), and writes:

* ``cv_table.csv`` and ``cv_table.md``: the best validation AUC of each fold, with mean and
  standard deviation, per score and model (random and oracle on the same episodes beside them);
* ``cv_coverage_by_view.png``: the validation coverage by view at each run's best epoch, averaged
  over the folds (the paper's Fig. 12).
"""

from __future__ import annotations

import argparse
import csv
import json
import logging
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from nbv.policies.episode import auc  # noqa: E402

log = logging.getLogger(__name__)


def find_runs(folder: Path) -> list[Path]:
    """Run folders (holding ``metrics.csv``) under ``folder``, directly or through ``run.json``."""
    runs = {p.parent.resolve() for p in folder.rglob("metrics.csv")}
    for pointer in folder.rglob("run.json"):
        target = Path(json.loads(pointer.read_text())["out_dir"])
        if (target / "metrics.csv").exists():
            runs.add(target.resolve())
    return sorted(runs)


def read_run(run: Path) -> dict | None:
    """Model, score, fold, best AUC and its coverage curve of one run (None if never evaluated)."""
    with open(run / "metrics.csv", newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r.get("val_auc")]
    if not rows:
        return None
    best = max(rows, key=lambda r: float(r["val_auc"]))
    settings = json.loads((run / "settings.json").read_text())
    reference = json.loads((run / "reference.json").read_text())
    curve = [float(best[f"val_cov_{i}"]) for i in range(1, 11) if best.get(f"val_cov_{i}")]
    return {
        "model": settings["model_name"],
        "score": settings["score"],
        "fold": int(settings["fold"]),
        "held_out": settings["held_out"],
        "best_epoch": int(best["epoch"]),
        "auc": float(best["val_auc"]),
        "curve": curve,
        "random_auc": auc(reference["random"]),
        "oracle_auc": auc(reference["oracle"]),
        "random_curve": reference["random"],
        "oracle_curve": reference["oracle"],
    }


def summarise(folder: Path, out: Path) -> list[dict]:
    """Write the table and plot for every run under ``folder`` into ``out``; returns the rows."""
    runs = [r for r in (read_run(p) for p in find_runs(folder)) if r is not None]
    if not runs:
        raise SystemExit(f"train.summary: no evaluated training runs under {folder}")
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for r in runs:
        groups[(r["model"], r["score"])].append(r)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for (model, score), items in sorted(groups.items()):
        items.sort(key=lambda r: r["fold"])
        aucs = np.array([r["auc"] for r in items])
        row = {"model": model, "score": score, "folds": len(items)}
        row.update({f"fold{r['fold']}_{r['held_out']}": round(r["auc"], 4) for r in items})
        row.update(
            auc_mean=round(float(aucs.mean()), 4),
            auc_std=round(float(aucs.std()), 4),
            random_auc_mean=round(float(np.mean([r["random_auc"] for r in items])), 4),
            oracle_auc_mean=round(float(np.mean([r["oracle_auc"] for r in items])), 4),
        )
        rows.append(row)
    columns = list(dict.fromkeys(k for r in rows for k in r))
    with open(out / "cv_table.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, columns)
        writer.writeheader()
        writer.writerows(rows)
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(str(r.get(c, "")) for c in columns) + " |" for r in rows]
    (out / "cv_table.md").write_text("\n".join(lines) + "\n")

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for (model, score), items in sorted(groups.items()):
        curves = np.array([r["curve"] for r in items if len(r["curve"]) == 10])
        if len(curves):
            ax.plot(range(1, 11), curves.mean(axis=0), marker="o", label=f"{model} ({score})")
    every = list(groups.values())[0]
    for name, style in (("random", ":"), ("oracle", "--")):
        ref = np.mean([r[f"{name}_curve"] for r in every], axis=0)
        ax.plot(range(1, 11), ref, style, color="gray", label=name)
    ax.set_xlabel("views")
    ax.set_ylabel("coverage (held-out category, mean over folds)")
    ax.set_title("Average coverage by view over the folds")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "cv_coverage_by_view.png", dpi=120)
    plt.close(fig)
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Cross-validation table of training runs.")
    parser.add_argument("folder", type=Path, help="a sweep folder or a folder of run folders")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: folder)")
    args = parser.parse_args(argv)
    out = args.out or args.folder
    summarise(args.folder, out)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    log.info("wrote %s and %s:\n%s", out / "cv_table.md", out / "cv_coverage_by_view.png",
             (out / "cv_table.md").read_text())  # fmt: skip


if __name__ == "__main__":
    main()
