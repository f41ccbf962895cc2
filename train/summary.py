"""``python -m train.summary folder=<sweep dir or runs dir> [out=DIR]``: the cross-validation table.

Finds every training run under the folder (a hydra sweep folder, whose jobs point at their run
folders through ``run.json``, or a folder of run folders such as ``outputs/train``) and reads each
run's ``heldout.json``: the held-out category's episodes of the checkpoint the run chose without
that category (:mod:`train.heldout`), with random (averaged over seeds), spread and the oracle on
the same episodes. It writes:

* ``cv_table.md`` and ``cv_table.csv``: per model and score, each fold's held-out AUC with its
  95 % bootstrap interval (models resampled), then over all folds' episodes the network, random,
  spread and the oracle, and the paired differences network - spread and network - random with
  their intervals;
* ``cv_folds.csv``: one row per run (fold), the same numbers;
* ``cv_coverage_by_view.png``: the held-out coverage by view averaged over the folds, with random,
  spread and the oracle (the paper's Fig. 12).

The baselines and the paired differences come from the registry
(:data:`nbv.policies.registry.BASELINES`).
Settings: ``conf/train_summary.yaml`` (declared by :class:`SummarySettings`); a folder without
finished runs ends with one line on stderr and exit status 2 (:mod:`nbv.config.cli`).
"""

from __future__ import annotations

import csv
import io
import logging
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from nbv.config.cli import command  # noqa: E402
from nbv.config.schema import PathsConfig  # noqa: E402
from nbv.config.settings import Entry  # noqa: E402
from nbv.policies.registry import BASELINES, METHODS  # noqa: E402
from nbv.utils.artefacts import check_array, read_json, reading  # noqa: E402
from nbv.utils.atomic import save_figure, write_text  # noqa: E402
from nbv.utils.markdown import md_table  # noqa: E402
from nbv.utils.stats import bootstrap_mean  # noqa: E402
from train.heldout import HELDOUT_FILE, HELDOUT_METHODS  # noqa: E402

PROG = "train.summary"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("train.summary")

#: Seed of every bootstrap interval of the summary.
SEED = 0
#: The baselines the network is paired with (network - baseline, per episode): those a robot
#: could run (not the oracle's ground truth), the last in the registry's order first.
PAIRED = tuple(reversed([m for m in BASELINES if not METHODS[m].ground_truth]))
#: Line styles of the baselines' curves, in :data:`BASELINES`' order.
_LINES = (":", "-.", "--", "-")


@dataclass(frozen=True)
class SummarySettings:
    """The cross-validation table of finished training runs (``python -m train.summary``).

    Attributes:
        folder: a hydra sweep folder of ``python -m train -m`` (its jobs point at their run
            folders through ``run.json``) or a folder of run folders (``outputs/train``).
        out: the folder the tables and the plot go to.
    """

    folder: Path
    out: Path = field(kw_only=True)


ENTRY = Entry("train_summary_schema", SummarySettings, extra=(("paths", PathsConfig),))


def find_runs(folder: Path) -> list[Path]:
    """Run folders (holding ``heldout.json``) under ``folder``, directly or through ``run.json``."""
    runs = {p.parent.resolve() for p in folder.rglob(HELDOUT_FILE)}
    for pointer in folder.rglob("run.json"):
        target = Path(str(read_json(pointer, "run pointer", ("out_dir",))["out_dir"]))
        if (target / HELDOUT_FILE).exists():
            runs.add(target.resolve())
    return sorted(runs)


def read_run(run: Path) -> dict:
    """Model, score, fold, the chosen epoch and the held-out episodes of one run folder."""
    settings_file, heldout_file = run / "settings.json", run / HELDOUT_FILE
    settings = read_json(settings_file, "training run's settings",
                         ("model_name", "score", "fold"))  # fmt: skip
    heldout = read_json(heldout_file, "held-out evaluation",
                        ("held_out", "checkpoint", "episodes", "auc", "coverage",
                         "random_repeats"))  # fmt: skip
    with reading(settings_file, "training run's settings"):
        fold = int(settings["fold"])
    with reading(heldout_file, "held-out evaluation"):
        episodes = heldout["episodes"]
        row = {
            "run": str(run),
            "model": str(settings["model_name"]),
            "score": str(settings["score"]),
            "fold": fold,
            "held_out": heldout["held_out"],
            "select": heldout["checkpoint"]["select"],
            "epoch": int(heldout["checkpoint"]["epoch"]) + 1,
            "keys": [f"{heldout['held_out']}/{k}" for k, _ in episodes],
            "auc": {m: np.asarray(heldout["auc"][m], float) for m in HELDOUT_METHODS},
            "coverage": {m: np.asarray(heldout["coverage"][m], float) for m in HELDOUT_METHODS},
            "random_repeats": int(heldout["random_repeats"]),
        }
    for kind in ("auc", "coverage"):
        for m, values in row[kind].items():
            check_array(values, heldout_file, f"{kind}/{m}",
                        (len(episodes),) if kind == "auc" else (len(episodes), None))  # fmt: skip
    return row


def _stats(keys: list[str], auc: dict[str, np.ndarray]) -> dict:
    """Means and intervals of the network and the paired differences (``minus_<baseline>``)
    over the given episodes."""
    net = auc["network"]
    return {
        "network": bootstrap_mean(net, keys, SEED),
        **{m: float(np.mean(auc[m])) for m in BASELINES},
        **{f"minus_{m}": bootstrap_mean(net - auc[m], keys, SEED) for m in PAIRED},
    }


def _columns(stats: dict) -> dict:
    """The CSV columns of one row's stats: the network's AUC with its interval, the baselines'
    means, the paired differences with their intervals."""
    net = stats["network"]
    out = {"auc": net.mean, "auc_low": net.low, "auc_high": net.high}
    out.update({m: stats[m] for m in BASELINES})
    for m in PAIRED:
        diff = stats[f"minus_{m}"]
        out.update({f"minus_{m}": diff.mean, f"minus_{m}_low": diff.low,
                    f"minus_{m}_high": diff.high})  # fmt: skip
    return out


def summarise(folder: Path, out: Path) -> list[dict]:
    """Write the tables and the plot for every run under ``folder`` into ``out``.

    Returns:
        One dict per (model, score): ``folds`` (per-fold stats) and ``all`` (pooled stats).

    Raises:
        ValueError: no run under ``folder`` has a ``heldout.json``.
    """
    return summarise_runs([read_run(p) for p in _runs_of(folder)], out)


def summarise_runs(runs: list[dict], out: Path) -> list[dict]:
    """:func:`summarise` of runs already read (:func:`read_run`)."""
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for r in runs:
        groups[(r["model"], r["score"])].append(r)
    out.mkdir(parents=True, exist_ok=True)
    results, fold_rows = [], []
    for (model, score), items in sorted(groups.items()):
        items.sort(key=lambda r: r["fold"])
        per_fold = [(r, _stats(r["keys"], r["auc"])) for r in items]
        keys = [k for r in items for k in r["keys"]]
        pooled = {m: np.concatenate([r["auc"][m] for r in items]) for m in HELDOUT_METHODS}
        results.append({"model": model, "score": score, "runs": items, "folds": per_fold,
                        "all": _stats(keys, pooled)})  # fmt: skip
        for r, st in per_fold:
            fold_rows.append({
                "model": model, "score": score, "fold": r["fold"], "held_out": r["held_out"],
                "select": r["select"], "epoch": r["epoch"], "episodes": len(r["keys"]),
                **_columns(st),
            })  # fmt: skip
    _write_csv(out / "cv_folds.csv", fold_rows)
    _write_csv(out / "cv_table.csv", [
        {"model": g["model"], "score": g["score"], "folds": len(g["runs"]),
         "episodes": g["all"]["network"].n, **_columns(g["all"])}
        for g in results
    ])  # fmt: skip
    write_text(out / "cv_table.md", table_markdown(results))
    _plot(results, out / "cv_coverage_by_view.png")
    return results


def table_markdown(results: list[dict]) -> str:
    """The Markdown of ``cv_table.md`` (see the module docstring)."""
    lines = [
        "Held-out category AUC of the checkpoint each fold chose without it, mean [95 % "
        "bootstrap interval over models]. Random is averaged over its seeds per episode; "
        "random, spread and the oracle play the same episodes.",
        "",
    ]
    folds = sorted({(r["fold"], r["held_out"]) for g in results for r in g["runs"]})
    rows = []
    for g in results:
        cells = {r["fold"]: st["network"].text(3, signed=False) for r, st in g["folds"]}
        rows.append([g["model"], g["score"]] + [cells.get(k, "") for k, _ in folds])
    lines += md_table(["model", "score", *[f"fold {k} ({c})" for k, c in folds]], rows)
    lines += ["", "Over all folds' held-out episodes:", ""]
    rows = []
    for g in results:
        a = g["all"]
        n = len(g["folds"])
        above = [sum(st[f"minus_{m}"].above_zero for _, st in g["folds"]) for m in PAIRED]
        rows.append([
            g["model"], g["score"], str(n), str(a["network"].n),
            a["network"].text(3, signed=False), *[f"{a[m]:.3f}" for m in BASELINES],
            *[a[f"minus_{m}"].text(3) for m in PAIRED], *[f"{k} of {n}" for k in above],
        ])  # fmt: skip
    header = [
        "model",
        "score",
        "folds",
        "episodes",
        "network",
        *BASELINES,
        *[f"network - {m}" for m in PAIRED],
        *[f"folds above {m}" for m in PAIRED],
    ]
    lines += md_table(header, rows)
    lines += [
        "",
        "A fold counts as above a baseline only when its whole interval of the paired "
        "difference lies above 0.",
    ]
    return "\n".join(lines) + "\n"


def _write_csv(path: Path, rows: list[dict]) -> None:
    columns = list(dict.fromkeys(k for r in rows for k in r))
    handle = io.StringIO()
    writer = csv.DictWriter(handle, columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(
        [{k: f"{v:.6f}" if isinstance(v, float) else v for k, v in r.items()} for r in rows]
    )
    write_text(path, handle.getvalue())


def _plot(results: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for g in results:
        curve = np.mean([r["coverage"]["network"].mean(axis=0) for r in g["runs"]], axis=0)
        x = np.arange(1, len(curve) + 1)
        ax.plot(x, curve, marker="o", label=f"{g['model']} ({g['score']})")
    runs = results[0]["runs"]
    for name, style in zip(BASELINES, _LINES, strict=False):
        ref = np.mean([r["coverage"][name].mean(axis=0) for r in runs], axis=0)
        ax.plot(np.arange(1, len(ref) + 1), ref, style, color="gray", label=name)
    ax.set_xlabel("views")
    ax.set_ylabel("coverage (held-out category, mean over folds)")
    ax.set_title("Coverage by view on the held-out categories")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def _runs_of(folder: Path) -> list[Path]:
    """:func:`find_runs`, refusing a folder without any.

    Raises:
        ValueError: no run under ``folder`` has a ``heldout.json``.
    """
    runs = find_runs(folder)
    if not runs:
        raise ValueError(f"no finished training runs (with {HELDOUT_FILE}) under {folder}")
    return runs


def _start(cfg) -> tuple[SummarySettings, list[dict]]:
    """The settings, and every run read and checked: nothing is written yet."""
    settings = ENTRY.build(cfg)
    return settings, [read_run(run) for run in _runs_of(settings.folder)]


def _finish(started: tuple[SummarySettings, list[dict]]) -> None:
    settings, runs = started
    out = settings.out
    summarise_runs(runs, out)
    log.info("wrote %s and %s:\n%s", out / "cv_table.md", out / "cv_coverage_by_view.png",
             (out / "cv_table.md").read_text())  # fmt: skip


main = command(PROG, "train_summary", _start, _finish)

if __name__ == "__main__":
    main()
