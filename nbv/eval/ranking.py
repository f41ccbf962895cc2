"""``python -m nbv.eval.ranking [methods=[...]] [out=outputs/ranking] [key=value]``: how well each
method's view scores rank the true coverage gains, on the evaluation's models.

Settings: ``conf/ranking.yaml`` (declared by :class:`RankingSettings`). A refused setting or
input (a method without per-view scores, a missing dataset, an unusable checkpoint) ends with
one line on stderr and exit status 2, and leaves no output folder behind (:mod:`nbv.config.cli`).

The states are the oracle's episodes (the evaluation's start views, each viewspace) after 1, ...,
``n_views - 1`` captured views: the same states for every method. Each method scores the states
of an episode in order with a fresh policy (the registry's, as the evaluator builds it, so an
incremental map grows as in an episode), through the policy's ``view_scores``: the scores it
picks its view by. For each state:

* Spearman's rank correlation of the scores against the true coverage gains of the unvisited
  views (a state whose unvisited views all gain alike has no ranks and is left out);
* whether the best-scored unvisited view is a best one by the true gain;
* the split-half reliability of the true gains' own ranking over the ground-truth points
  (:func:`~nbv.utils.ranking.split_half_reliability`): late in an episode a view gains a
  handful of points, and their order is then largely the sampling's.

Written to ``out``: ``ranking.md`` (mean Spearman with a 95 % interval resampling the models;
minus spread, paired on the same states, over both viewspaces and per viewspace; best-view
hits; Spearman per category, or per model
for a mesh folder; Spearman per number of captured views beside the truth's reliability) and
``ranking.json`` (every state's values). Methods without per-view scores (the oracle, the
one-shot hull planners) are refused with the list of those that have them.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from nbv.config.cli import command
from nbv.config.schema import PathsConfig
from nbv.config.settings import Entry, setting
from nbv.dataset.records import ModelData, score_functions
from nbv.eval.config import DisturbSettings, EvalSettings, names_setting
from nbv.eval.inputs import (
    dataset_context,
    exclude_selection,
    open_inputs,
    with_shipped_weights,
)
from nbv.eval.prepare import read_model
from nbv.geometry.camera import Intrinsics
from nbv.geometry.scores import DEFAULT_EPS
from nbv.infogain.gain_scorer import load_scorer
from nbv.policies.episode import EPISODE_VIEWS, EpisodeState
from nbv.policies.method import MethodContext
from nbv.policies.reference import OraclePolicy
from nbv.policies.registry import METHODS, NETWORK_INPUTS, SCORED, SPREAD
from nbv.scan.shipped import with_shipped
from nbv.setcover.settings import SetCoverSettings
from nbv.utils.atomic import write_text
from nbv.utils.fields import at_least, or_null
from nbv.utils.markdown import md_table
from nbv.utils.ranking import best_view_hit, spearman_per_sample, split_half_reliability
from nbv.utils.stats import Interval, bootstrap_mean

PROG = "nbv.eval.ranking"
log = logging.getLogger("nbv.eval.ranking")


def _ranked() -> tuple[str, ...]:
    """The registry's methods whose policies score every view (``view_scores``), in its order.

    A network method's policy has them (both network policies define ``view_scores``), and so
    does a network matched by direction (``matched_network``); a method led by another's
    network (a two-stage planner) has none; any other method's policy is built once, with
    default settings, to see.
    """
    ctx = with_shipped(
        MethodContext({}, SetCoverSettings(), Intrinsics(), DEFAULT_EPS, EPISODE_VIEWS)
    )
    return tuple(
        m.name
        for m in METHODS.values()
        if m.network_input is not None
        or m.matched_network
        or (
            m.network is None
            and callable(getattr(m.build(ctx, np.random.default_rng(0)), "view_scores", None))
        )
    )


#: The methods whose policies have per-view scores (``view_scores``).
RANKED = _ranked()
#: The methods ranked when none are given: the PCNBV networks (inputs points and signature) are
#: left out (their scores do not rank the unseen models' views); the methods without a network
#: first, then the viewspace-conditioned networks.
DEFAULT_METHODS = (
    *(m for m in RANKED if m not in NETWORK_INPUTS and not METHODS[m].matched),
    *(m for m in RANKED if NETWORK_INPUTS.get(m) == "directions"),
)


def oracle_states(model: ModelData, viewspace: str, start: int, n_views: int) -> list[EpisodeState]:
    """The states of the oracle's episode from ``start`` (:class:`OraclePolicy` on coverage):
    after 1, ..., ``n_views - 1`` captured views."""
    oracle = OraclePolicy("coverage")
    views = model.captured(viewspace)
    n = len(views.poses)
    true_gains = functools.partial(model.view_gains, viewspace)
    order, out = [start], []
    for _ in range(n_views - 1):
        state = np.zeros(n, dtype=bool)
        state[order] = True
        out.append(EpisodeState(views, state, list(order)))  # what the ranked methods see
        order.append(oracle(dataclasses.replace(out[-1], true_gains=true_gains)))
    return out


def score_states(
    model: ModelData,
    viewspace: str,
    start: int,
    methods: tuple[str, ...],
    ctx: MethodContext,
    seed: int,
) -> list[dict]:
    """One record per state of the oracle's episode: each method's Spearman and best-view hit
    (``{"spearman": {method: value or None}, "hit": {method: bool}, ...}``) and the split-half
    reliability of the true gains' ranking (``truth_reliability``, None where undefined;
    :func:`~nbv.utils.ranking.split_half_reliability`)."""
    states = oracle_states(model, viewspace, start, ctx.n_views)
    gains, _ = score_functions(model, "coverage", viewspace)
    truth = np.stack([gains(s.view_state) for s in states])
    visited = np.stack([s.view_state for s in states])
    n_gt = len(model.gt_points)
    covered = np.unpackbits(model.views[viewspace].coverage, axis=1, count=n_gt).astype(bool)
    splits = np.random.default_rng([seed, start, n_gt])
    records = []
    for s in states:
        reliability = split_half_reliability(covered, s.view_state, splits)
        records.append({"viewspace": viewspace, "start": start, "captured": len(s.order),
                        "truth_reliability": None if np.isnan(reliability) else reliability,
                        "spearman": {}, "hit": {}})  # fmt: skip
    for name in methods:
        policy = METHODS[name].build(ctx, np.random.default_rng([seed, start]))
        scores = np.stack([policy.view_scores(s) for s in states])
        rho = spearman_per_sample(scores, truth, visited)
        hits = best_view_hit(scores, truth, visited)
        for i, record in enumerate(records):
            record["spearman"][name] = None if np.isnan(rho[i]) else float(rho[i])
            record["hit"][name] = bool(hits[i])
    return records


def ranking(settings: EvalSettings, seed: int = 0) -> list[dict]:
    """Every state record of every selected model (``model`` and ``category`` added), in the
    order of the models, viewspaces and start views."""
    from tqdm import tqdm

    refused = [m for m in settings.methods if m not in RANKED]
    if refused:
        raise ValueError(f"methods {refused} have no per-view scores; allowed: {', '.join(RANKED)}")
    settings = with_shipped_weights(settings)
    opened, networks, skipped, _ = open_inputs(settings)
    if skipped:
        raise ValueError("; ".join(f"{m}: {reason}" for m, reason in skipped.items()))
    scorer = load_scorer(settings.scorer_file()) if set(SCORED) & set(settings.methods) else None
    records = []
    for info, ds in opened:
        exclude_selection(info, ds, networks)
        ctx = dataset_context(settings, ds, networks, scorer)
        for key in tqdm(info.keys, desc=f"ranking {info.name}", disable=not settings.progress):
            model = read_model(ds, info.rendered, key, settings.viewspaces)
            for vs in settings.viewspaces:
                for start in settings.start_views:
                    for r in score_states(model, vs, start, settings.methods, ctx, seed):
                        records.append({"model": key, "category": ds.index[key][1], **r})
    return records


def summary(records: list[dict], methods: tuple[str, ...]) -> list[dict]:
    """Per method: states ranked, mean Spearman (95 % interval resampling the models), minus
    spread on the states both rank (paired, when spread is among ``methods``), both per
    viewspace too (``by_viewspace``, ``minus_spread_by_viewspace``: viewspace -> interval),
    best-view hits, the mean Spearman per category (``by_group``; per model when there is one
    category, as for a mesh folder; ``by`` says which) and per number of captured views
    (``by_captured``; ``by_captured_viewspace``: viewspace -> those means on its states)."""

    def values(name: str) -> np.ndarray:
        return np.array([r["spearman"][name] for r in records], dtype=float)  # None -> NaN

    models = np.array([r["model"] for r in records])

    def interval(x: np.ndarray, keep: np.ndarray) -> Interval:
        """The mean of ``x`` over the states ``keep`` marks, resampling their models."""
        return bootstrap_mean(x[keep], models[keep])

    captured = np.array([r["captured"] for r in records])
    viewspace = np.array([r["viewspace"] for r in records])
    in_space = {v: viewspace == v for v in sorted(set(viewspace.tolist()))}
    by = "category" if len({r["category"] for r in records}) > 1 else "model"
    groups = np.array([r[by] for r in records])
    base = values(SPREAD.name) if SPREAD.name in methods else None
    names = sorted(set(groups))
    rows = []
    for name in methods:
        rho = values(name)
        ok = np.isfinite(rho)
        row = {"method": name, "states": int(ok.sum()), "spearman": interval(rho, ok),
               "hits": float(np.mean([r["hit"][name] for r in records])), "by": by,
               "by_group": {g: _mean(rho[groups == g]) for g in names},
               "by_captured": _by_captured(rho, captured),
               "by_captured_viewspace": {v: _by_captured(rho[m], captured[m])
                                         for v, m in in_space.items()},
               "by_viewspace": {v: interval(rho, ok & m) for v, m in in_space.items()}}  # fmt: skip
        if base is not None and name != SPREAD.name:
            both = ok & np.isfinite(base)
            row["minus_spread"] = interval(rho - base, both)
            row["minus_spread_by_viewspace"] = {
                v: interval(rho - base, both & m) for v, m in in_space.items()
            }
        rows.append(row)
    return rows


def reliability_summary(records: list[dict]) -> dict | None:
    """The true gains' split-half reliability (``truth_reliability`` of the records): states
    where it is defined, its mean with a 95 % interval resampling the models, and its mean per
    number of captured views (``by_captured``); None where it is nowhere defined."""
    truth = np.array([r.get("truth_reliability") for r in records], dtype=float)  # None -> NaN
    ok = np.isfinite(truth)
    if not ok.any():
        return None
    models = np.array([r["model"] for r in records])
    captured = np.array([r["captured"] for r in records])
    return {"states": int(ok.sum()), "mean": bootstrap_mean(truth[ok], models[ok]),
            "by_captured": _by_captured(truth, captured)}  # fmt: skip


def _by_captured(values: np.ndarray, captured: np.ndarray) -> dict[int, float]:
    """Mean of the finite ``values`` of the states with each number of captured views."""
    return {int(c): _mean(values[captured == c]) for c in sorted(set(captured.tolist()))}


def _mean(values: np.ndarray) -> float:
    """Mean over the finite values; NaN when there are none (without numpy's warning)."""
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if len(finite) else float("nan")


def write(out: Path, records: list[dict], rows: list[dict], truth: dict | None) -> None:
    """``ranking.json`` (every state) and ``ranking.md`` (the summary tables of
    :func:`summary`'s ``rows`` and :func:`reliability_summary`'s ``truth``)."""
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "ranking.json", json.dumps({"states": records}))
    groups = list(rows[0]["by_group"])
    steps = list(rows[0]["by_captured"])
    lines = md_table(
        ["method", "states", "Spearman [95 %]", "minus spread [95 %]", "best-view hits"],
        [[r["method"], str(r["states"]), r["spearman"].text(),
          r["minus_spread"].text() if "minus_spread" in r else "", f"{r['hits']:.3f}"]
         for r in rows],
    )  # fmt: skip
    lines += [
        "",
        "Spearman by viewspace (95 % intervals resampling the models; a network trained "
        "on one viewspace's view order meets a permuted one only through the geometry):",
        "",
        *_viewspace_table(rows),
    ]
    lines += ["", f"Spearman by {rows[0]['by']}:", "",
              *md_table(["method", *groups],
                        [[r["method"], *(f"{r['by_group'][g]:.2f}" for g in groups)]
                         for r in rows])]  # fmt: skip
    by_step = []
    for r in rows:
        per = r["by_captured_viewspace"]
        split = [(f"{r['method']}, {v}", per[v]) for v in per] if len(per) > 1 else []
        for label, means in [(r["method"], r["by_captured"]), *split]:
            by_step.append([label, *(f"{means.get(c, np.nan):.2f}" for c in steps)])
    text = "Spearman by views captured"
    if truth is not None:
        cells = [f"{truth['by_captured'].get(c, np.nan):.2f}" for c in steps]
        by_step.append(["true gains' split-half reliability", *cells])
        text += (f", and the split-half reliability of the true gains' ranking (mean "
                 f"{truth['mean'].text(signed=False)} over {truth['states']} states): a "
                 "scorer's Spearman can hardly exceed its square root")  # fmt: skip
    lines += ["", f"{text}:", "", *md_table(["method", *map(str, steps)], by_step)]
    write_text(out / "ranking.md", "\n".join([*lines, ""]))


def _viewspace_table(rows: list[dict]) -> list[str]:
    """The markdown lines of each method's Spearman per viewspace, and minus spread's where
    :func:`summary` paired it."""
    spaces = list(rows[0]["by_viewspace"])
    paired = any("minus_spread_by_viewspace" in r for r in rows)
    header = ["method"]
    for v in spaces:
        header += [v, f"{v} minus spread"] if paired else [v]
    body = []
    for r in rows:
        cells = [r["method"]]
        for v in spaces:
            cells.append(r["by_viewspace"][v].text())
            if paired:
                minus = r.get("minus_spread_by_viewspace")
                cells.append(minus[v].text() if minus else "")
        body.append(cells)
    return md_table(header, body)


@dataclass(frozen=True)
class RankingSettings:
    """What ``python -m nbv.eval.ranking`` ranks, and where it writes (``conf/ranking.yaml``).

    The episodes are ``python -m nbv.eval``'s defaults (:class:`~nbv.eval.config.EvalSettings`):
    its start views, both viewspaces, 10 views, seed 0, its planner settings.

    Attributes:
        methods: the methods to rank (a name or a list), any of those with per-view scores
            (:data:`RANKED`); by default those without a network, then the
            viewspace-conditioned networks (:data:`DEFAULT_METHODS`).
        out: the output folder: ``ranking.md``, ``ranking.json`` and the log ``ranking.log``.
        data_dir: a dataset folder made by ``make dataset``.
        dataset: the models (one of ``nbv.eval``'s ``dataset``): ``unseen``, ``test``,
            ``meshes`` (with ``mesh_dir``), ``ycb`` or ``scans``.
        mesh_dir: a folder of mesh files (``dataset=meshes``); null = none.
        limit: at most this many models (spread over the categories); null = all.
        checkpoints: network method name -> its checkpoint (``checkpoints.vcnbv_map=<best.pt>``);
            a checkpoint that is not there falls back to the weights the package ships.
    """

    methods: tuple[str, ...] = names_setting("methods", DEFAULT_METHODS)
    out: Path = Path("outputs/ranking")
    data_dir: Path = Path("data/generated/synthetic")
    dataset: str = "unseen"
    mesh_dir: Path | None = None
    limit: int | None = setting(None, allows=or_null(at_least(1)))
    checkpoints: dict[str, str] = setting(factory=dict)

    def __post_init__(self) -> None:
        self.evaluation()  # its checks: names, checkpoint entries, mesh_dir

    def evaluation(self) -> EvalSettings:
        """The evaluation whose models and episodes are ranked (no disturbance checks)."""
        return EvalSettings(
            run=self.out.name, out_root=self.out.parent, methods=self.methods,
            datasets=(self.dataset,), data_dir=self.data_dir, mesh_dir=self.mesh_dir,
            limit=self.limit, checkpoints=dict(self.checkpoints),
            disturb=DisturbSettings(checks=()),
        )  # fmt: skip


#: ``python -m nbv.eval.ranking``: the schema ``ranking_schema`` and the builder.
ENTRY = Entry("ranking_schema", RankingSettings, extra=(("paths", PathsConfig),))


def start(cfg: Any) -> tuple[RankingSettings, list[dict]]:
    """The settings, checked, and every state's record: a ValueError on the way (a method
    without per-view scores, a missing dataset, an unusable checkpoint) refuses the run."""
    s = ENTRY.build(cfg)
    return s, ranking(s.evaluation())


def finish(started: tuple[RankingSettings, list[dict]]) -> None:
    """Write the tables and log each method's mean Spearman."""
    s, records = started
    rows = summary(records, s.methods)
    write(s.out, records, rows, reliability_summary(records))
    for r in rows:
        per = ", ".join(f"{v} {i.text()}" for v, i in r["by_viewspace"].items())
        log.info("%s: Spearman %s over %d states (%s)", r["method"], r["spearman"].text(),
                 r["states"], per)  # fmt: skip


main = command(PROG, "ranking", start, finish)

if __name__ == "__main__":
    main()
