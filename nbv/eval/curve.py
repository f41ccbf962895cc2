"""``python -m nbv.eval.curve <run folder> ... [--out outputs/curve]``: the learning curve of a
learner over the number of training models.

Each run folder is a ``python -m train.conditioned`` run (``max_models=N``; its ``best.pt`` plays
as ``vcnbv``, or as ``vcnbv_map`` when it reads map features) or a ``python -m train.scorer`` run
(its ``scorer.json`` plays as ``ig_learned``); the folders of one curve are of one kind. Each
plays the unseen categories on both viewspaces (``nbv.eval``, the same episodes as ``make
eval``), and random, spread and the oracle play them once, as horizontal lines. Written to
``--out``: ``curve.md`` (a table: models, chosen epoch, the validation score the run chose by,
unseen AUC, minus spread with a 95 % interval, models resampled), ``curve.png`` and the
evaluations themselves (``eval_*``; rerunning reuses what they hold).
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
from nbv.planning.scorer import load_scorer
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


def _evaluate(out: Path, name: str, methods: tuple[str, ...], data_dir: Path, **kw) -> Path:
    folder = out / f"eval_{name}"
    settings = EvalSettings(out_dir=folder, methods=methods, data_dir=data_dir, checks=(),
                            plots=False, progress=False, **kw)  # fmt: skip
    run_eval(settings)
    return folder


def _learner(run: Path) -> tuple[str, dict, dict]:
    """``(method, evaluation settings, row start)`` of a run folder: the method it plays, what
    the evaluation needs to play it, and its training models, chosen epoch and validation."""
    scorer = run / "scorer.json"
    if scorer.is_file():
        info = load_scorer(scorer).info
        return "ig_learned", {"ig_scorer": scorer}, {
            "models": int(info["train_models"]), "epoch": int(info["epoch"]),
            "validation": f"{info['val_captured']:.3f} (ig {info['val_captured_ig']:.3f})",
        }  # fmt: skip
    net, extra = load_conditioned(run / "best.pt")
    chosen = extra["rows"][int(extra["epoch"])]
    method = "vcnbv_map" if net.config.map_features else "vcnbv"
    return method, {"checkpoints": {method: str(run / "best.pt")}}, {
        "models": int(extra.get("train_models") or extra["settings"].get("max_models") or 32),
        "epoch": int(extra["epoch"]) + 1,
        "validation": f"{chosen['val_auc_original']:.3f} / {chosen['val_auc_permuted']:.3f}",
    }  # fmt: skip


def curve(runs: list[Path], out: Path, data_dir: Path) -> list[dict]:
    """Evaluate every run and the baselines; returns one row per run (fewest models first)."""
    base = _episodes(_evaluate(out, "baselines", BASELINES, data_dir))
    learners = [_learner(run) for run in runs]
    kinds = {method for method, _, _ in learners}
    if len(kinds) > 1:
        raise ValueError(f"the runs of one curve must be of one kind, got {sorted(kinds)}")
    rows = []
    for run, (method, kw, start) in zip(runs, learners, strict=True):
        episodes = _episodes(_evaluate(out, run.name, (method,), data_dir, **kw))
        row = {"run": str(run), "method": method, **start}
        for vs in VIEWSPACES:
            net = _auc_by_episode(episodes, method, vs)
            spread = _auc_by_episode(base, "spread", vs)
            shared = sorted(set(net) & set(spread))
            diff = bootstrap_mean([net[k] - spread[k] for k in shared], [k for k, _ in shared])
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

    method = rows[0]["method"]
    validation = ("val AUC orig / perm" if method.startswith("vcnbv")
                  else "val share of the best gain")  # fmt: skip
    table = md_table(
        ["training models", "epoch", validation, "unseen AUC orig / perm",
         "minus spread, original", "minus spread, permuted"],
        [[str(r["models"]), str(r["epoch"]), r["validation"],
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
        ax.plot([r["models"] for r in rows], [r[f"auc_{vs}"] for r in rows], "o-", label=method)
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
    parser.add_argument("runs", nargs="+", type=Path,
                        help="train.conditioned or train.scorer run folders")  # fmt: skip
    parser.add_argument("--out", type=Path, default=Path("outputs/curve"))
    parser.add_argument("--data-dir", type=Path, default=Path("data/generated/synthetic"))
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO)
    args.out.mkdir(parents=True, exist_ok=True)
    for row in curve(args.runs, args.out, args.data_dir):
        print(json.dumps(row))


if __name__ == "__main__":
    main()
