"""Training of the viewspace-conditioned network (:mod:`nbv.models.view_conditioned`).

``python -m train.conditioned [key=value ...]`` (``conf/train_conditioned.yaml``).

The network sees a different viewspace in every sample, so that no view index means anything to
it. A sample is drawn from one training model of the dataset, whose views from *both* stored
viewspaces (66 directions with their true coverage bits) are the pool:

1. ``candidates`` of the pool's directions, drawn at random, in random order, are the sample's
   viewspace (an original ring, a permuted one, a mix: new directions in the same band);
2. the object and those directions are turned by one random rotation about the up axis, and
   mirrored with probability 1/2: the same physical scene, so the gains are unchanged;
3. a trajectory from a random seen candidate: at each step the best unvisited candidate by true
   coverage gain, or with probability ``random_step_prob`` a random one; before each pick a
   sample is stored (cloud: ``train_points`` random points of the visited views' stored points,
   the directions, the view state and the true gains of the candidates).

With ``map_features=true`` (the ``vcnbv_map`` variant) a sample also holds each unvisited
candidate's map features (:func:`nbv.infogain.view_features.view_features`) on the occupancy map
of ``ig`` (its default settings) of the visited views, built in the model's own frame: the
features are counts along rays and angles, which the turn of step 2 leaves unchanged.

Every epoch draws new samples from ``(seed, epoch)``. The checkpoint kept as ``best.pt`` has the
best mean validation AUC over the ``original`` and ``permuted`` viewspaces, on the *valid* split
of the training categories; the unseen categories take no part. With ``select_categories`` the
validation models are instead every model (train and valid splits) of those training categories,
which then take no part in training: the checkpoint is chosen, and the validation Spearman
measured, on categories the network never saw, as the unseen ones will be.

``out_dir`` gets ``best.pt``, ``last.pt`` and ``metrics.csv`` (train and validation loss and
Spearman, AUC per viewspace).
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import torch

import nbv.dataset
from nbv.config.cli import command
from nbv.dataset.records import ModelData
from nbv.geometry.camera import Intrinsics
from nbv.geometry.scores import coverage_gains
from nbv.geometry.viewspace import unit_directions
from nbv.infogain.gain import candidate_voxels
from nbv.infogain.occupancy import OccupancyMap, OccupancySettings
from nbv.infogain.settings import InfoGainSettings
from nbv.infogain.view_features import FEATURES, unvisited_features
from nbv.models.networks import fresh_network
from nbv.models.view_conditioned import (
    load_conditioned,
    save_conditioned,
)
from nbv.policies.conditioned_network import ConditionedPolicy
from nbv.policies.episode import auc, run_episode
from nbv.policies.infogain import InfoGainPolicy
from nbv.utils.selection import masked_argmax
from train.conditioned_config import ENTRY, VIEWSPACES, ConditionedSettings
from train.losses import batch_loss
from train.metrics import SPEARMAN_FILE, spearman, spearman_by_model
from train.run_log import append_csv_rows
from train.subsets import subset

log = logging.getLogger("train.conditioned")
PROG = "train.conditioned"


@dataclass(frozen=True)
class _Pool:
    """One model's views of both viewspaces: directions, coverage bits, stored points; for map
    features also each view's effect on the map (``seen``,
    :meth:`OccupancyMap.captured_voxels`) and its rays' voxels as a candidate (``rays``)."""

    directions: np.ndarray  # (P, 3) unit
    bits: np.ndarray  # (P, bytes)
    points: list[np.ndarray]  # P arrays (n_v, 3)
    n_gt: int
    positions: np.ndarray  # (P, 3) camera centres
    grid: OccupancySettings | None = None  # the map's, with map features
    seen: list[tuple[np.ndarray, np.ndarray]] | None = None
    rays: np.ndarray | None = None  # (P, R, S)


def _pool(
    model: ModelData, intrinsics: Intrinsics, infogain: InfoGainSettings | None = None
) -> _Pool:
    """The pool of ``model``; with the map's ``infogain`` settings, its map data too."""
    views = [model.views[name] for name in VIEWSPACES]
    poses = np.concatenate([v.poses for v in views])
    points = [v.view_points(i) for v in views for i in range(len(v.poses))]
    grid, seen, rays = None, None, None
    if infogain is not None:
        grid = infogain.occupancy()
        tracer = OccupancyMap(grid)
        seen = [tracer.captured_voxels(p, pose, intrinsics, infogain.block)
                for p, pose in zip(points, poses, strict=True)]  # fmt: skip
        rays = candidate_voxels(poses, intrinsics, infogain.columns, grid)
    return _Pool(
        directions=unit_directions(poses[:, :3, 3], np.float32),
        bits=np.concatenate([v.coverage for v in views]),
        points=points,
        n_gt=len(model.gt_points),
        positions=poses[:, :3, 3],
        grid=grid,
        seen=seen,
        rays=rays,
    )


def _turn(rng: np.random.Generator) -> np.ndarray:
    """A random rotation about the up axis (y), mirrored in x with probability 1/2: (3, 3)."""
    a = rng.uniform(0, 2 * np.pi)
    m = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    return m @ np.diag([-1.0, 1, 1]) if rng.random() < 0.5 else m


def draw_samples(pools: list[_Pool], settings: ConditionedSettings, rng: np.random.Generator):
    """An epoch's samples (see the module docstring): arrays ``points (S, n, 3)``,
    ``directions (S, C, 3)``, ``view_state (S, C)`` bool, ``target (S, C)`` float32 and
    ``pick (S, C)``, the candidates' rows in their model's pool, and ``model (S,)``, the
    sample's index in ``pools``; with ``settings.map_features`` also ``features (S, C, F)``
    float32."""
    keys = ["points", "directions", "view_state", "target", "pick", "model"]
    out: dict[str, list] = {k: [] for k in keys + ["features"] * settings.map_features}
    for row, pool in enumerate(pools):
        for _ in range(settings.trajectories):
            pick = rng.choice(len(pool.directions), settings.candidates, replace=False)
            turn = _turn(rng)
            directions = (pool.directions[pick] @ turn.T).astype(np.float32)
            bits = pool.bits[pick]
            seen = [i for i, p in enumerate(pick) if len(pool.points[p])]
            if not seen:
                continue
            order = [int(rng.choice(seen))]
            state = np.zeros(settings.candidates, bool)
            state[order] = True
            if settings.map_features:  # the trajectory's map; its candidates' rays
                occupancy, rays = OccupancyMap(pool.grid), pool.rays[pick]
            for _ in range(min(settings.steps, settings.candidates - 1)):
                gains = coverage_gains(bits, state, pool.n_gt).astype(np.float32)
                cloud = np.concatenate([pool.points[p] for p in pick[state]])
                subset = rng.choice(
                    len(cloud), settings.train_points, len(cloud) < settings.train_points
                )
                out["points"].append((cloud[subset] @ turn.T).astype(np.float32))
                out["directions"].append(directions)
                out["view_state"].append(state.copy())
                out["target"].append(gains)
                out["pick"].append(pick)
                out["model"].append(row)
                if settings.map_features:
                    occupancy.apply_view(pool.seen[pick[order[-1]]])
                    features = unvisited_features(occupancy, rays, pool.positions[pick], order)
                    out["features"].append(features.astype(np.float32))
                if rng.random() < settings.random_step_prob:
                    nxt = int(rng.choice(np.flatnonzero(~state)))
                else:
                    nxt = masked_argmax(gains, state)
                state[nxt] = True
                order.append(int(nxt))
    return {k: np.stack(v) for k, v in out.items()}


def _tensors(samples: dict, index: np.ndarray) -> list[torch.Tensor | None]:
    """``points, directions, view_state, target, features`` of the samples ``index``
    (``features`` None without map features)."""
    out = [
        torch.from_numpy(samples[k][index].astype(np.float32))
        for k in ("points", "directions", "view_state", "target")
    ]
    return out + [torch.from_numpy(samples["features"][index]) if "features" in samples else None]


def _predict(model, samples: dict, batch_size: int) -> np.ndarray:
    model.eval()
    preds = []
    with torch.no_grad():
        for start in range(0, len(samples["points"]), batch_size):
            x, d, s, _, f = _tensors(
                samples, np.arange(start, min(start + batch_size, len(samples["points"])))
            )
            preds.append(model(x, d, s, f).numpy())
    return np.concatenate(preds)


def _validation_auc(
    model, dataset, keys: list[str], settings: ConditionedSettings, infogain: InfoGainSettings
) -> dict:
    """Mean validation AUC per viewspace; a network of map features plays on ``infogain``'s
    map."""
    policy = ConditionedPolicy(model, settings.eval_points)
    traced: dict = {}
    result = {}
    for name in VIEWSPACES:
        curves = [
            run_episode(
                dataset.model(key, (name,)), name, int(start),
                policy.fresh(InfoGainPolicy(infogain, dataset.intrinsics, traced=traced)),
            ).coverage
            for key in keys
            for start in settings.start_views
        ]  # fmt: skip
        result[f"val_auc_{name}"] = auc(np.mean(curves, axis=0))
    return result


def _resume(last: Path, plain: dict, model, optimizer) -> tuple[list[dict], float, int]:
    """``(rows, best, first epoch)`` of the run in ``last`` when it holds the same settings
    (its weights and optimizer loaded into ``model`` and ``optimizer``), else a fresh start.

    Raises:
        ValueError: ``last`` was trained with other settings.
    """
    if not last.exists():
        return [], -np.inf, 0
    saved, extra = load_conditioned(last)
    if not _same_run(extra.get("settings"), plain):
        raise ValueError(f"{last} was trained with other settings; set another out_dir")
    model.load_state_dict(saved.state_dict())
    opt = extra["optimizer"]
    opt["state"] = {int(k): v for k, v in opt["state"].items()}
    optimizer.load_state_dict(opt)
    first = int(extra["epoch"]) + 1
    log.info("resuming at epoch %d", first + 1)
    return list(extra["rows"]), float(extra["best"]), first


def _train_epoch(model, optimizer, samples: dict, order: np.ndarray,
                 settings: ConditionedSettings) -> list[float]:  # fmt: skip
    """One pass over ``samples`` in ``order``, batch by batch; the batches' losses."""
    model.train()
    losses = []
    for i in range(0, len(order), settings.batch_size):
        x, d, s, t, f = _tensors(samples, order[i : i + settings.batch_size])
        optimizer.zero_grad()
        loss = batch_loss(settings.loss, model(x, d, s, f), t, s)
        loss.backward()
        optimizer.step()
        losses.append(loss.item())
    return losses


def run(settings: ConditionedSettings) -> dict:
    """Train; returns the last epoch's metrics and the chosen epoch. Resumes from ``last.pt``
    when it holds the same settings but, perhaps, fewer ``epochs``: an epoch's samples come from
    ``(seed, epoch)`` and the learning rate is constant, so a run extended to more epochs equals
    one started with them."""
    if settings.threads:
        torch.set_num_threads(settings.threads)
    dataset = nbv.dataset.open(settings.dataset)
    train_keys, valid_keys = split_models(dataset, settings)
    categories_of = [dataset.index[k][1] for k in train_keys]
    train_keys = subset(train_keys, categories_of, settings.max_models, settings.seed)
    held = ", ".join(settings.select_categories)
    log.info("%d training, %d validation models%s", len(train_keys), len(valid_keys),
             f" (of {held})" if held else "")  # fmt: skip
    infogain = InfoGainSettings()  # ig's defaults: the map of the map features
    pooled = infogain if settings.map_features else None
    t0 = time.perf_counter()
    pools = [_pool(dataset.model(k, VIEWSPACES), dataset.intrinsics, pooled)
             for k in train_keys]  # fmt: skip
    val_pools = [_pool(dataset.model(k, VIEWSPACES), dataset.intrinsics, pooled)
                 for k in valid_keys]  # fmt: skip
    log.info("views of %d models read in %.0f s", len(pools) + len(val_pools),
             time.perf_counter() - t0)  # fmt: skip
    val_samples = draw_samples(val_pools, settings, np.random.default_rng([settings.seed, 10**6]))
    torch.manual_seed(settings.seed)
    net = replace(settings.net, map_features=len(FEATURES) if settings.map_features else 0)
    model = fresh_network("vcnbv", net)
    optimizer = torch.optim.Adam(model.parameters(), lr=settings.lr)
    out = settings.out_dir
    out.mkdir(parents=True, exist_ok=True)
    plain = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(settings).items()}
    for key in ("start_views", "categories", "select_categories"):
        plain[key] = list(plain[key])
    plain["net"] = net.to_dict()
    last = out / "last.pt"
    rows, best, first = _resume(last, plain, model, optimizer)
    for epoch in range(first, settings.epochs):
        t0 = time.perf_counter()
        rng = np.random.default_rng([settings.seed, epoch])
        samples = draw_samples(pools, settings, rng)
        log.info("epoch %d: %d samples drawn in %.0f s", epoch + 1, len(samples["points"]),
                 time.perf_counter() - t0)  # fmt: skip
        order = rng.permutation(len(samples["points"]))
        losses = _train_epoch(model, optimizer, samples, order, settings)
        probe = {k: v[order[:300]] for k, v in samples.items()}
        train_pred = _predict(model, probe, settings.batch_size)
        val_pred = _predict(model, val_samples, settings.batch_size)
        row = {
            "epoch": epoch + 1,
            "samples": len(order),
            "train_loss": float(np.mean(losses)),
            "train_spearman": spearman(train_pred, probe["target"], probe["view_state"]),
            "val_spearman": spearman(val_pred, val_samples["target"], val_samples["view_state"]),
            **_validation_auc(model, dataset, valid_keys, settings, infogain),
            "seconds": time.perf_counter() - t0,
        }
        by_model = spearman_by_model(val_pred, val_samples["target"], val_samples["view_state"],
                                     np.asarray(valid_keys)[val_samples["model"]])  # fmt: skip
        append_csv_rows(out / SPEARMAN_FILE, [{"epoch": epoch + 1, **r} for r in by_model])
        rows.append(row)
        log.info("epoch %d: %s", epoch + 1, {k: round(v, 4) for k, v in row.items()})
        score = np.mean([row[f"val_auc_{v}"] for v in VIEWSPACES])
        extra = {"settings": plain, "eval_points": settings.eval_points, "epoch": epoch,
                 "selection_keys": valid_keys, "rows": rows,
                 "train_models": len(train_keys)}  # fmt: skip
        if score > best:
            best = float(score)
            save_conditioned(out / "best.pt", model, extra)
        opt = optimizer.state_dict()
        opt["state"] = {str(k): v for k, v in opt["state"].items()}
        save_conditioned(last, model, {**extra, "best": best, "optimizer": opt})
        append_csv_rows(out / "metrics.csv", [row])
    return {"last": rows[-1], "best_val_auc": best}


def split_models(dataset, settings: ConditionedSettings) -> tuple[list[str], list[str]]:
    """The training and the validation models of ``dataset``: the train and the valid split of
    the training categories, or, with ``select_categories``, the train split of the others and
    every train and valid model of those.

    Raises:
        ValueError: either list is empty.
    """
    chosen = set(settings.select_categories)
    trained = set(settings.categories) - chosen

    def of(categories: set[str], *splits: str) -> list[str]:
        keys = [k for s in splits for k in dataset.keys(split=s)]
        return [k for k in keys if dataset.index[k][1] in categories]

    train_keys = of(trained, "train")
    valid_keys = of(chosen, "train", "valid") if chosen else of(trained, "valid")
    if not train_keys or not valid_keys:
        where = f"of {', '.join(sorted(chosen))} " if chosen else ""
        raise ValueError(
            f"{settings.dataset}: {len(train_keys)} training and {len(valid_keys)} validation "
            f"models {where}among the training categories; both are needed"
        )
    return train_keys, valid_keys


#: Settings added after runs were trained, with the value those runs had (they resume).
_ADDED = {"select_categories": []}


def _same_run(saved: dict | None, wanted: dict) -> bool:
    """Whether a checkpoint's settings continue into ``wanted``: equal but for ``epochs``, which
    may grow, and ``out_dir`` (a copied run folder goes on where the copy stopped)."""
    if saved is None:
        return False
    saved = {**_ADDED, **saved}
    free = ("epochs", "out_dir")
    rest = {k: v for k, v in saved.items() if k not in free}
    wanted_rest = {k: v for k, v in wanted.items() if k not in free}
    return rest == wanted_rest and saved.get("epochs", 0) <= wanted["epochs"]


def _start(cfg) -> tuple[ConditionedSettings, dict]:
    """The settings, then the training: what stops it before it has written anything (bad
    settings, too few models, a run folder of other settings) raises ValueError."""
    settings = ENTRY.build(cfg)
    return settings, run(settings)


def _finish(started: tuple[ConditionedSettings, dict]) -> None:
    settings, result = started
    log.info("done: best mean validation AUC %.4f in %s", result["best_val_auc"], settings.out_dir)


main = command(PROG, "train_conditioned", _start, _finish)

if __name__ == "__main__":
    main()
