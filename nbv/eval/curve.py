"""``python -m nbv.eval.curve runs=[<run folder>,...] [out=outputs/curve]``: the learning curve
of a learner over the number of training models.

Settings: ``conf/curve.yaml`` (declared by :class:`CurveSettings`). The run folders are read
before any evaluation: one that is not a training run, or runs of two kinds, end the command
with one line on stderr and exit status 2 (:mod:`nbv.config.cli`).

Each run folder is a ``python -m train.conditioned`` run (``max_models=N``; its ``best.pt`` plays
as the viewspace-conditioned network method, ``vcnbv``, or ``vcnbv_map`` when it reads map
features), a ``python -m train.scorer`` run (its ``scorer.json`` plays as the learned-score
method, ``ig_learned``) or a ``python -m train`` run (its ``best.pt`` plays as ``pcnbv``,
``pcnbv_sph`` or their ``_vig`` methods; its training models are counted in its dataset); the
folders of one curve are of one kind. Each
plays the unseen categories on both viewspaces (``nbv.eval``, the same episodes as ``make
eval``), and the baselines (random, spread and the oracle) play them once, as horizontal lines.
Written to ``out``: ``curve.md`` (a table: models, chosen epoch, the validation score the run
chose by, unseen AUC, minus spread with a 95 % interval, models resampled), ``curve.png`` and
the evaluations themselves (``eval_*``; rerunning reuses what they hold).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import nbv.dataset
from nbv.config.cli import command
from nbv.config.schema import PathsConfig
from nbv.config.settings import Entry, setting
from nbv.eval.config import VIEWSPACES, DisturbSettings, EvalSettings
from nbv.eval.evaluate import run as run_eval
from nbv.infogain.gain_scorer import load_scorer
from nbv.models.checkpoints import CHECKPOINT_FORMAT, load_checkpoint
from nbv.models.view_conditioned import load_conditioned
from nbv.policies.registry import BASELINES, METHODS, NETWORK_INPUTS, SCORED, SPREAD
from nbv.utils.atomic import save_figure, write_text
from nbv.utils.markdown import md_table
from nbv.utils.stats import bootstrap_mean

PROG = "nbv.eval.curve"
log = logging.getLogger("nbv.eval.curve")
# The reference lines are the registry's BASELINES: the coverage methods with neither a network
# nor a planner (random, spread, the oracle), in registry order.
#: The viewspace-conditioned network methods: the plain one, then the one reading map features
#: (the registry's order; it has no attribute for the map features yet).
CONDITIONED = tuple(m for m, kind in NETWORK_INPUTS.items() if kind == "directions")
#: The method a ``scorer.json`` plays as (the registry's one method ranking by a score file).
(LEARNED_SCORE,) = SCORED


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


def _evaluate(
    out: Path, name: str, methods: tuple[str, ...], data_dir: Path,
    checkpoints: Mapping[str, str], extra: Mapping[str, Any] | None = None,
) -> Path:  # fmt: skip
    """Run (or resume) the evaluation ``eval_<name>`` of ``methods``; ``extra`` holds further
    :class:`EvalSettings` (a learner's, :func:`_learner`), whose ``checkpoints`` replace
    ``checkpoints``."""
    folder = out / f"eval_{name}"
    kw = {"checkpoints": dict(checkpoints), **(extra or {})}
    settings = EvalSettings(run=folder.name, out_root=out, methods=methods, data_dir=data_dir,
                            disturb=DisturbSettings(checks=()), plots=False, progress=False,
                            **kw)  # fmt: skip
    run_eval(settings)
    return folder


def _learner(run: Path) -> tuple[str, dict, dict]:
    """``(method, evaluation settings, row start)`` of a run folder: the method it plays, what
    the evaluation needs to play it, and its training models, chosen epoch and validation."""
    scorer = run / "scorer.json"
    if scorer.is_file():
        info = load_scorer(scorer).info
        return LEARNED_SCORE, {"ig_scorer": scorer}, {
            "models": int(info["train_models"]), "epoch": int(info["epoch"]),
            "validation": f"{info['val_captured']:.3f} (ig {info['val_captured_ig']:.3f})",
        }  # fmt: skip
    if _format(run / "best.pt") == CHECKPOINT_FORMAT:
        return _network_learner(run)
    net, extra = load_conditioned(run / "best.pt")
    chosen = extra["rows"][int(extra["epoch"])]
    plain, mapped = CONDITIONED
    method = mapped if net.config.map_features else plain
    return method, {"checkpoints": {method: str(run / "best.pt")}}, {
        "models": int(extra.get("train_models") or extra["settings"].get("max_models") or 32),
        "epoch": int(extra["epoch"]) + 1,
        "validation": f"{chosen['val_auc_original']:.3f} / {chosen['val_auc_permuted']:.3f}",
    }  # fmt: skip


def _format(path: Path) -> str | None:
    """The ``format`` a checkpoint file records (None for anything else)."""
    import torch

    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # any unreadable file: the loaders name it and the reason
        return None
    return payload.get("format") if isinstance(payload, dict) else None


def _network_learner(run: Path) -> tuple[str, dict, dict]:
    """:func:`_learner` of a ``python -m train`` run: it plays as the registry's method of its
    input and score (``pcnbv``, ``pcnbv_sph``, ``pcnbv_vig``, ``pcnbv_sph_vig``); its training
    models are its dataset's train split less the held-out category."""
    _, extra = load_checkpoint(run / "best.pt")
    s = extra["settings"]
    (method,) = (m for m, kind in NETWORK_INPUTS.items()
                 if kind == extra["input"] and METHODS[m].score == s["score"])  # fmt: skip
    ds = nbv.dataset.open(s["dataset"])
    held_out = extra.get("held_out")
    models = sum(ds.index[k][1] != held_out for k in ds.keys(split="train"))
    chosen = extra["metrics"]
    return method, {"checkpoints": {method: str(run / "best.pt")}}, {
        "models": models, "epoch": int(extra["epoch"]) + 1,
        "validation": f"{chosen['val_auc']:.3f} ({chosen['val_spearman']:+.3f})",
        "validation_label": "val AUC (Spearman), original",
    }  # fmt: skip


def learners(runs: list[Path]) -> list[tuple[str, dict, dict]]:
    """:func:`_learner` of every run folder.

    Raises:
        ValueError: a folder that is not a training run (no usable ``best.pt``), or runs that
            play as different methods.
    """
    found = [_learner(run) for run in runs]
    kinds = {method for method, _, _ in found}
    if len(kinds) > 1:
        raise ValueError(f"the runs of one curve must be of one kind, got {sorted(kinds)}")
    return found


def curve(
    runs: list[Path], out: Path, data_dir: Path, checkpoints: Mapping[str, str] | None = None
) -> list[dict]:
    """Evaluate every run and the baselines; returns one row per run (fewest models first).

    Args:
        runs: the run folders (:func:`learners`).
        out: the output folder.
        data_dir: the dataset whose unseen categories are played.
        checkpoints: the network checkpoints the evaluations record (``nbv.eval``'s,
            ``paths.checkpoints``; no evaluation runs them): they are part of an evaluation's
            identity, so a rerun resumes the evaluations of an earlier one. A conditioned run's
            evaluation records its own checkpoint alone.
    """
    checkpoints = checkpoints or {}
    trained = learners(runs)
    base = _episodes(_evaluate(out, "baselines", BASELINES, data_dir, checkpoints))
    rows = []
    for run, (method, kw, start) in zip(runs, trained, strict=True):
        episodes = _episodes(_evaluate(out, run.name, (method,), data_dir, checkpoints, kw))
        row = {"run": str(run), "method": method, **start}
        for vs in VIEWSPACES:
            net = _auc_by_episode(episodes, method, vs)
            spread = _auc_by_episode(base, SPREAD.name, vs)
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
    validation = rows[0].get("validation_label") or (
        "val AUC orig / perm" if METHODS[method].network_input is not None
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
    write_text(
        out / "curve.md", "\n".join([*table, "", f"Unseen AUC, original / permuted: {ref}.", ""])
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
    save_figure(fig, out / "curve.png", dpi=120)
    plt.close(fig)


@dataclass(frozen=True)
class CurveSettings:
    """The runs of one learning curve and where it is written (``conf/curve.yaml``).

    Attributes:
        runs: the run folders (one or more), all of ``python -m train.conditioned``, all of
            ``python -m train.scorer`` or all of ``python -m train`` of one model and score,
            e.g. one per ``max_models`` or per dataset size.
        out: the output folder: ``curve.md``, ``curve.png``, the evaluations ``eval_*`` (a rerun
            reuses what they hold) and the log ``curve.log``.
        data_dir: a dataset folder made by ``make dataset``; its unseen categories are played.
    """

    runs: tuple[Path, ...] = setting(check=lambda v: len(v) >= 1, allowed="one or more run folders")
    out: Path = Path("outputs/curve")
    data_dir: Path = Path("data/generated/synthetic")


#: ``python -m nbv.eval.curve``: the schema ``curve_schema`` and the builder.
ENTRY = Entry("curve_schema", CurveSettings, extra=(("paths", PathsConfig),))


def start(cfg: Any) -> tuple[CurveSettings, dict[str, str]]:
    """The settings and the run folders, checked (:func:`learners`) before any evaluation, and
    the shared network checkpoints (``paths.checkpoints``) the evaluations record."""
    from omegaconf import OmegaConf

    s = ENTRY.build(cfg)
    learners(list(s.runs))
    return s, OmegaConf.to_container(cfg.paths.checkpoints, resolve=True)


def finish(started: tuple[CurveSettings, dict[str, str]]) -> None:
    """Evaluate; print each row as one JSON line on stdout."""
    s, checkpoints = started
    s.out.mkdir(parents=True, exist_ok=True)
    for row in curve(list(s.runs), s.out, s.data_dir, checkpoints):
        print(json.dumps(row))


main = command(PROG, "curve", start, finish)

if __name__ == "__main__":
    main()
