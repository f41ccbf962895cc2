"""``python -m nbv.eval.curve <run folder> ... [--out outputs/curve]``: the learning curve of the
viewspace-conditioned network over the number of training models.

Each run folder is a ``python -m train.conditioned`` run (``max_models=N``). Its ``best.pt`` plays
the unseen categories on both viewspaces (``nbv.eval``, the same episodes as ``make eval``), and
random, spread and the oracle play them once, as horizontal lines. Written to ``--out``:
``curve.md`` (a table: models, chosen epoch, validation AUC, unseen AUC, minus spread with a 95 %
interval, models resampled), ``curve.png`` and the evaluations themselves (``eval_*``; rerunning
reuses what they hold).
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import numpy as np

from nbv.eval.config import EvalSettings
from nbv.eval.evaluate import run as run_eval
from nbv.models.conditioned import load_conditioned
from nbv.utils.markdown import md_table
from nbv.utils.stats import bootstrap_mean

log = logging.getLogger("nbv.eval.curve")
VIEWSPACES = ("original", "permuted")
BASELINES = ("random", "spread", "oracle")


def _episodes(folder: Path) -> list[dict]:
    return [e for e in json.loads((folder / "results.json").read_text())["episodes"]
            if e["check"] is None]  # fmt: skip


def _auc_by_episode(episodes: list[dict], method: str, viewspace: str) -> dict[tuple, float]:
    """(key, start) -> AUC (random averaged over its repeats)."""
    out: dict[tuple, list[float]] = {}
    for e in episodes:
        if e["method"] == method and e["viewspace"] == viewspace:
            out.setdefault((e["key"], e["start"]), []).append(e["auc"])
    return {k: float(np.mean(v)) for k, v in out.items()}


def _evaluate(out: Path, name: str, methods: tuple[str, ...], data_dir: Path, ckpt=None) -> Path:
    folder = out / f"eval_{name}"
    settings = EvalSettings(
        out_dir=folder, methods=methods, data_dir=data_dir, checks=(), plots=False,
        progress=False, checkpoints={"vcnbv": str(ckpt)} if ckpt else {},
    )  # fmt: skip
    run_eval(settings)
    return folder


def curve(runs: list[Path], out: Path, data_dir: Path) -> list[dict]:
    """Evaluate every run and the baselines; returns one row per run (fewest models first)."""
    base = _episodes(_evaluate(out, "baselines", BASELINES, data_dir))
    rows = []
    for run in runs:
        _, extra = load_conditioned(run / "best.pt")
        models = int(extra.get("train_models") or extra["settings"].get("max_models") or 32)
        epoch = int(extra["epoch"])
        chosen = extra["rows"][epoch]
        episodes = _episodes(_evaluate(out, run.name, ("vcnbv",), data_dir, run / "best.pt"))
        row = {"run": str(run), "models": models, "epoch": epoch + 1}
        for vs in VIEWSPACES:
            net = _auc_by_episode(episodes, "vcnbv", vs)
            spread = _auc_by_episode(base, "spread", vs)
            shared = sorted(set(net) & set(spread))
            diff = bootstrap_mean([net[k] - spread[k] for k in shared], [k for k, _ in shared])
            row[f"val_{vs}"] = float(chosen[f"val_auc_{vs}"])
            row[f"auc_{vs}"] = float(np.mean([net[k] for k in shared]))
            row[f"minus_spread_{vs}"] = diff.text()
        rows.append(row)
    rows.sort(key=lambda r: r["models"])
    lines = {f"{m}_{vs}": float(np.mean(list(_auc_by_episode(base, m, vs).values())))
             for m in BASELINES for vs in VIEWSPACES}  # fmt: skip
    _write(out, rows, lines)
    return rows


def _write(out: Path, rows: list[dict], lines: dict[str, float]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = md_table(
        ["training models", "epoch", "val AUC orig / perm", "unseen AUC orig / perm",
         "minus spread, original", "minus spread, permuted"],
        [[str(r["models"]), str(r["epoch"]), f"{r['val_original']:.3f} / {r['val_permuted']:.3f}",
          f"{r['auc_original']:.3f} / {r['auc_permuted']:.3f}", r["minus_spread_original"],
          r["minus_spread_permuted"]] for r in rows],
    )  # fmt: skip
    ref = ", ".join(f"{m} {lines[f'{m}_original']:.3f} / {lines[f'{m}_permuted']:.3f}"
                    for m in BASELINES)  # fmt: skip
    (out / "curve.md").write_text(
        "\n".join([*table, "", f"Unseen AUC, original / permuted: {ref}.", ""])
    )
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharey=True)
    for ax, vs in zip(axes, VIEWSPACES, strict=True):
        ax.plot([r["models"] for r in rows], [r[f"auc_{vs}"] for r in rows], "o-", label="vcnbv")
        for m, style in zip(BASELINES, (":", "-.", "--"), strict=True):
            ax.axhline(lines[f"{m}_{vs}"], ls=style, color="k", lw=1, label=m)
        ax.set_xscale("log", base=2)
        ax.set_xlabel("training models")
        ax.set_title(f"unseen categories, {vs} viewspace")
    axes[0].set_ylabel("AUC")
    axes[1].legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "curve.png", dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(prog="nbv.eval.curve", description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="train.conditioned run folders")
    parser.add_argument("--out", type=Path, default=Path("outputs/curve"))
    parser.add_argument("--data-dir", type=Path, default=Path("data/generated/synthetic"))
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO)
    args.out.mkdir(parents=True, exist_ok=True)
    for row in curve(args.runs, args.out, args.data_dir):
        print(json.dumps(row))


if __name__ == "__main__":
    main()
