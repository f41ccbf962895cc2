"""Training of ``ig_learned``'s score (:mod:`nbv.infogain.gain_scorer`).

``python -m train.scorer [key=value ...]`` (``conf/train_scorer.yaml``).

1. **Decisions.** On every training model of the training categories, for both viewspaces and
   ``mixes`` viewspaces of 33 views drawn at random from the model's 66 (new directions in the
   same elevation band, in a random order), ``starts`` episodes from seeded random start views
   run to ``n_views`` views on the occupancy map of ``ig`` (its default settings). Before each
   pick the decision's candidates are stored: their features
   (:func:`nbv.infogain.view_features.view_features`) and their true coverage gains. The
   next view is ``ig``'s pick with probability ``ig_step_prob``, the oracle's with
   ``oracle_step_prob``, a random unvisited view otherwise: the decisions then cover the states
   the planner meets and better ones. The models of the *valid* split give the validation
   decisions the same way. They are computed once and kept in ``out_dir/decisions.npz`` (reused
   when the settings and the dataset are the same).
2. **Fit.** A perceptron (``hidden`` units per layer) learns the ranking with the ``normalised``
   loss of :mod:`train.losses` (squared error against the gains over the decision's best gain),
   each decision weighted by its best gain when ``weight_by_gain``, as AUC weighs it: the first
   picks, which gain most, count most.
   ``max_models=N`` trains on N of the training models (the categories in turn, nested sets, as
   ``python -m train.conditioned`` draws them): a learning curve's sizes.
3. **Choice.** ``scorer.json`` is the epoch whose picks capture the largest share of the best
   gain on the validation decisions (``val_captured``, beside ``ig``'s own share). The unseen
   categories take no part. ``metrics.csv`` has a row per epoch (with the mean Spearman
   correlation of the scores and the true gains over the decisions, on 2,000 fixed training
   decisions and on the validation ones), ``val_spearman_by_model.csv`` a row per epoch and
   validation model.
"""

from __future__ import annotations

import json
import logging
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

import nbv.dataset
from nbv.assets.categories import TRAIN_CATEGORIES
from nbv.config.cli import command
from nbv.config.schema import ConfigError, PathsConfig
from nbv.config.settings import Entry, check_ranges, setting
from nbv.dataset.records import ViewData, offsets_of, score_functions
from nbv.infogain.gain_scorer import GainScorer, save_scorer
from nbv.infogain.settings import InfoGainSettings
from nbv.infogain.view_features import FEATURES, view_features
from nbv.policies.episode import EpisodeState
from nbv.policies.infogain import InfoGainPolicy
from nbv.utils.fields import at_least, between, positive
from train.losses import per_sample_loss
from train.metrics import SPEARMAN_FILE, spearman, spearman_by_model
from train.run_log import append_csv_rows, dataset_identity
from train.subsets import subset

log = logging.getLogger("train.scorer")
PROG = "train.scorer"
VIEWSPACES = ("original", "permuted")
DECISIONS = "decisions.npz"


@dataclass(frozen=True)
class ScorerSettings:
    """Training of ``ig_learned``'s score (``python -m train.scorer``).

    Attributes:
        dataset: a dataset folder with both viewspaces (``make dataset``).
        out_dir: where ``scorer.json``, ``decisions.npz``, ``metrics.csv`` and
            ``val_spearman_by_model.csv`` go.
        seed: seeds the decisions, the network's initialisation and the epochs' order.
        starts: episodes per model and viewspace (seeded random start views), each to
            ``n_views`` views.
        mixes: beside the original and permuted viewspaces, this many of 33 views drawn from
            the model's 66 (new directions in the same elevation band, in a random order).
        n_views: views per training episode, the start view included.
        ig_step_prob: the next view of a training episode is ig's pick with this probability,
            the oracle's with ``oracle_step_prob``, a random unvisited view otherwise.
        oracle_step_prob: see ``ig_step_prob``; at most ``1 - ig_step_prob``.
        hidden: units of each hidden layer of the perceptron.
        epochs: training epochs.
        batch_size: decisions per step.
        lr: Adam's learning rate.
        weight_by_gain: weigh each decision by its best true gain (as the AUC weighs it);
            false: every decision alike.
        workers: processes that make the decisions.
        max_models: train on this many of the training models (the categories in turn, a
            seeded order in each; smaller sets are nested in larger ones): the learning curve's
            sizes. 0 = all.
        categories: the training categories (not a key: always
            :data:`~nbv.assets.categories.TRAIN_CATEGORIES`; ``scorer.json`` stores it).
    """

    dataset: Path
    out_dir: Path
    seed: int = 0
    starts: int = setting(8, allows=at_least(1))
    mixes: int = setting(1, allows=at_least(0))
    n_views: int = setting(10, allows=at_least(2))
    ig_step_prob: float = setting(0.5, allows=between(0, 1))
    # Its upper bound depends on ig_step_prob: checked in __post_init__, with the same words.
    oracle_step_prob: float = setting(
        0.25, check=lambda v: v >= 0, allowed="in [0, 1 - ig_step_prob]"
    )
    hidden: tuple[int, ...] = setting(
        (32, 32), check=lambda v: all(h >= 1 for h in v), allowed="a list of integers >= 1"
    )
    epochs: int = setting(30, allows=at_least(1))
    batch_size: int = setting(256, allows=at_least(1))
    lr: float = setting(1e-3, allows=positive())
    weight_by_gain: bool = True
    workers: int = setting(2, allows=at_least(1))
    max_models: int = setting(0, allows=at_least(0, note="0: every training model"))
    # Not a key (the schema has no such key): every run trains on the same categories.
    categories: tuple[str, ...] = field(default=TRAIN_CATEGORIES, init=False)

    def __post_init__(self) -> None:
        check_ranges(self)
        if self.oracle_step_prob > 1 - self.ig_step_prob:
            raise ConfigError(
                f"oracle_step_prob={self.oracle_step_prob!r}: must be in [0, 1 - ig_step_prob]"
            )


ENTRY = Entry("train_scorer_schema", ScorerSettings, extra=(("paths", PathsConfig),))


def mixed_views(views: list[ViewData], picks: np.ndarray) -> ViewData:
    """A viewspace of views taken from several: ``picks`` (K, 2) rows of (which of ``views``,
    which view of it), in that order; each view keeps its pose, points, coverage and hull."""
    chosen = [(views[i], int(v)) for i, v in picks]
    points = [view.view_points(v) for view, v in chosen]
    hulls = [view.hull_points[view.hull_offsets[v] : view.hull_offsets[v + 1]]
             for view, v in chosen]  # fmt: skip
    return ViewData(
        poses=np.stack([view.poses[v] for view, v in chosen]),
        points=np.concatenate(points),
        offsets=offsets_of(points),
        coverage=np.stack([view.coverage[v] for view, v in chosen]),
        hull_points=np.concatenate(hulls),
        hull_offsets=offsets_of(hulls),
        points_per_view=views[0].points_per_view,
    )


def model_decisions(
    dataset_path: Path, key: str, row: int, settings: ScorerSettings
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The decisions of one model (module docstring, step 1): ``(features (C, F), gains (C,))``
    per decision, the candidates being the unvisited views. Seeded by ``(seed, row)``."""
    dataset = nbv.dataset.open(dataset_path)
    model = dataset.model(key, VIEWSPACES)
    rng = np.random.default_rng([settings.seed, row])
    stored = [model.views[name] for name in VIEWSPACES]
    pool = np.array([(i, v) for i, view in enumerate(stored) for v in range(len(view.poses))])
    for m in range(settings.mixes):
        picks = pool[rng.choice(len(pool), len(stored[0].poses), replace=False)]
        model.views[f"mix{m}"] = mixed_views(stored, picks)
    traced: dict = {}
    out = []
    for name in model.views:
        view = model.views[name]
        gains_of, _ = score_functions(model, "coverage", name)
        positions = view.poses[:, :3, 3]
        n = len(positions)
        for start in rng.choice(n, min(settings.starts, n), replace=False):
            policy = InfoGainPolicy(InfoGainSettings(), dataset.intrinsics, traced=traced)
            order, state = [int(start)], np.zeros(n, bool)
            state[start] = True
            while len(order) < min(settings.n_views, n):
                policy.update(EpisodeState(model.captured(name), state.copy(), list(order)))
                candidates = np.flatnonzero(~state)
                voxels = policy.candidate_voxels(view.poses)[candidates]
                features = view_features(policy.occupancy, voxels, positions, order, candidates)
                gains = gains_of(state)[candidates]
                out.append((features.astype(np.float32), gains.astype(np.float32)))
                u = rng.random()
                if u < settings.ig_step_prob:  # FEATURES[0] ranks as ig does
                    pick = candidates[np.argmax(features[:, 0])]
                elif u < settings.ig_step_prob + settings.oracle_step_prob:
                    pick = candidates[np.argmax(gains)]
                else:
                    pick = rng.choice(candidates)
                order.append(int(pick))
                state[pick] = True
    return out


def _padded(decisions: list[tuple[np.ndarray, np.ndarray]], models: np.ndarray) -> dict:
    """Decisions as arrays: ``features (D, C, F)``, ``gains (D, C)``, ``pad (D, C)`` bool
    (True where a decision has fewer candidates than the most) and ``model (D,)``, the row of
    each decision's model."""
    width = max(len(g) for _, g in decisions)
    features = np.zeros((len(decisions), width, len(FEATURES)), np.float32)
    gains = np.zeros((len(decisions), width), np.float32)
    pad = np.ones((len(decisions), width), bool)
    for i, (f, g) in enumerate(decisions):
        features[i, : len(g)], gains[i, : len(g)], pad[i, : len(g)] = f, g, False
    return {"features": features, "gains": gains, "pad": pad, "model": models}


def all_decisions(keys: list[str], rows: list[int], settings: ScorerSettings):
    """:func:`model_decisions` of every key, in ``settings.workers`` processes, padded."""
    args = [(settings.dataset, k, r, settings) for k, r in zip(keys, rows, strict=True)]
    if settings.workers == 1:
        parts = [model_decisions(*a) for a in args]
    else:
        with ProcessPoolExecutor(settings.workers) as pool:
            parts = list(pool.map(model_decisions, *zip(*args, strict=True)))
    models = np.concatenate([np.full(len(part), i) for i, part in enumerate(parts)])
    return _padded([d for part in parts for d in part], models)


def captured(scores: np.ndarray, gains: np.ndarray, pad: np.ndarray) -> float:
    """The share of the best gain that the highest-scoring candidates capture, summed over the
    decisions: ``sum gain[argmax score] / sum max gain`` (1 = the oracle's picks); padded
    candidates (``pad``) take no part."""
    s = np.where(pad, -np.inf, scores)
    picked = np.take_along_axis(gains, s.argmax(axis=1)[:, None], axis=1)[:, 0]
    best = np.where(pad, -np.inf, gains).max(axis=1)
    return float(picked.sum() / max(best.sum(), 1e-12))


def _network(settings: ScorerSettings) -> torch.nn.Sequential:
    layers: list[torch.nn.Module] = []
    width = len(FEATURES)
    for h in settings.hidden:
        layers += [torch.nn.Linear(width, h), torch.nn.ReLU()]
        width = h
    return torch.nn.Sequential(*layers, torch.nn.Linear(width, 1))


def _scorer(net: torch.nn.Sequential, info: dict) -> GainScorer:
    linear = [m for m in net if isinstance(m, torch.nn.Linear)]
    return GainScorer(
        tuple(m.weight.detach().double().numpy().T.copy() for m in linear),
        tuple(m.bias.detach().double().numpy().copy() for m in linear),
        info,
    )


def _loss(net, batch: dict[str, torch.Tensor], weight_by_gain: bool) -> torch.Tensor:
    scores = net(batch["features"]).squeeze(-1)
    losses = per_sample_loss("normalised", scores, batch["gains"], batch["pad"].float())
    top = batch["gains"].amax(dim=1)
    weight = top if weight_by_gain else (top > 0).float()
    return (losses * weight).sum() / weight.sum().clamp_min(1e-12)


def _decisions_of(settings: ScorerSettings, split: str, keys: list[str], rows: list[int]) -> dict:
    """The decisions of ``keys`` (seeded by their ``rows``), from ``out_dir/decisions.npz`` when
    it was made with the same settings and dataset (its ``meta`` says), else computed and added
    to it."""
    path = settings.out_dir / DECISIONS
    plain = _plain(settings)
    meta = {"identity": dataset_identity(settings.dataset), "keys": keys,
            "settings": {k: plain[k] for k in ("seed", "starts", "mixes", "n_views",
                                               "ig_step_prob", "oracle_step_prob")}}  # fmt: skip
    stored = dict(np.load(path)) if path.exists() else {}
    if f"{split}_meta" in stored and json.loads(str(stored[f"{split}_meta"])) == meta:
        return {k: stored[f"{split}_{k}"] for k in ("features", "gains", "pad", "model")}
    t0 = time.perf_counter()
    made = all_decisions(keys, rows, settings)
    log.info("%s: %d decisions of %d models in %.0f s", split, len(made["gains"]), len(keys),
             time.perf_counter() - t0)  # fmt: skip
    stored.update({f"{split}_{k}": v for k, v in made.items()})
    stored[f"{split}_meta"] = np.array(json.dumps(meta))
    tmp = path.with_name("decisions.tmp.npz")
    np.savez_compressed(tmp, **stored)
    os.replace(tmp, path)
    return made


def _plain(settings: ScorerSettings) -> dict:
    plain = asdict(settings)
    plain.update(dataset=str(settings.dataset), out_dir=str(settings.out_dir),
                 hidden=list(settings.hidden), categories=list(settings.categories))  # fmt: skip
    return plain


def run(settings: ScorerSettings) -> dict:
    """Make the decisions, fit, write ``scorer.json`` and ``metrics.csv``; returns the chosen
    epoch's row."""
    dataset = nbv.dataset.open(settings.dataset)
    categories = set(settings.categories)
    keys = {s: [k for k in dataset.keys(split=s) if dataset.index[k][1] in categories]
            for s in ("train", "valid")}  # fmt: skip
    if not keys["train"] or not keys["valid"]:
        raise ValueError(
            f"{settings.dataset}: {len(keys['train'])} train and {len(keys['valid'])} valid "
            "models of the training categories; both are needed"
        )
    settings.out_dir.mkdir(parents=True, exist_ok=True)
    # A model's decisions are seeded by its place among all training models, so the smaller
    # training sets of a learning curve hold the same decisions of the same models.
    every = keys["train"]
    categories_of = [dataset.index[k][1] for k in every]
    keys["train"] = subset(every, categories_of, settings.max_models, settings.seed)
    train = _decisions_of(settings, "train", keys["train"], [every.index(k) for k in keys["train"]])
    valid = _decisions_of(settings, "valid", keys["valid"],
                          list(range(len(every), len(every) + len(keys["valid"]))))  # fmt: skip
    log.info("%d training, %d validation models", len(keys["train"]), len(keys["valid"]))
    ig_share = captured(valid["features"][..., 0], valid["gains"], valid["pad"])
    tensors = {k: torch.from_numpy(train[k]) for k in ("features", "gains", "pad")}
    val_tensors = {k: torch.from_numpy(valid[k]) for k in ("features", "gains", "pad")}
    probe = np.random.default_rng([settings.seed, 2]).permutation(len(train["gains"]))[:2000]
    torch.manual_seed(settings.seed)
    net = _network(settings)
    optimizer = torch.optim.Adam(net.parameters(), lr=settings.lr)
    rng = np.random.default_rng([settings.seed, 1])
    info = {"settings": _plain(settings), "dataset_identity": dataset_identity(settings.dataset),
            "train_models": len(keys["train"]), "selection_keys": keys["valid"]}  # fmt: skip
    metrics = settings.out_dir / "metrics.csv"
    by_model_file = settings.out_dir / SPEARMAN_FILE
    metrics.unlink(missing_ok=True)
    by_model_file.unlink(missing_ok=True)
    best: dict = {}
    for epoch in range(settings.epochs):
        t0 = time.perf_counter()
        net.train()
        order = torch.from_numpy(rng.permutation(len(train["gains"])))
        losses = []
        for i in range(0, len(order), settings.batch_size):
            batch = {k: v[order[i : i + settings.batch_size]] for k, v in tensors.items()}
            optimizer.zero_grad()
            loss = _loss(net, batch, settings.weight_by_gain)
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
        net.eval()
        with torch.no_grad():
            val_loss = _loss(net, val_tensors, settings.weight_by_gain).item()
            val_scores = net(val_tensors["features"]).squeeze(-1).numpy()
            probe_scores = net(tensors["features"][probe]).squeeze(-1).numpy()
        row = {"epoch": epoch + 1, "train_loss": float(np.mean(losses)), "val_loss": val_loss,
               "val_captured": captured(val_scores, valid["gains"], valid["pad"]),
               "val_captured_ig": ig_share,
               "train_spearman": spearman(probe_scores, train["gains"][probe], train["pad"][probe]),
               "val_spearman": spearman(val_scores, valid["gains"], valid["pad"]),
               "seconds": time.perf_counter() - t0}  # fmt: skip
        append_csv_rows(metrics, [row])
        by_model = spearman_by_model(val_scores, valid["gains"], valid["pad"],
                                     np.asarray(keys["valid"])[valid["model"]])  # fmt: skip
        append_csv_rows(by_model_file, [{"epoch": epoch + 1, **r} for r in by_model])
        log.info("epoch %d: %s", epoch + 1, {k: round(v, 4) for k, v in row.items()})
        if not best or row["val_captured"] > best["val_captured"]:
            best = row
            chosen = {**info, "epoch": epoch + 1, "val_captured": row["val_captured"],
                      "val_captured_ig": ig_share}  # fmt: skip
            save_scorer(settings.out_dir / "scorer.json", _scorer(net, chosen))
    return best


def _start(cfg) -> tuple[ScorerSettings, dict]:
    """The settings, then the decisions and the fit: what stops them before anything is written
    (bad settings, too few models) raises ValueError."""
    settings = ENTRY.build(cfg)
    return settings, run(settings)


def _finish(started: tuple[ScorerSettings, dict]) -> None:
    settings, best = started
    log.info("done: epoch %d captures %.4f of the best gain on the validation decisions (ig "
             "%.4f); %s", best["epoch"], best["val_captured"], best["val_captured_ig"],
             settings.out_dir / "scorer.json")  # fmt: skip


main = command(PROG, "train_scorer", _start, _finish)

if __name__ == "__main__":
    main()
