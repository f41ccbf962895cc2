"""How well a completion network completes captured clouds: CD-L1 and F-score against the ground
truth, next to the partial cloud itself and its best mirror completion.

Every distance is in the dataset's normalised frame (the object within radius 0.5 of the
origin, Y up). Per model and start view, the captured cloud of k views is the start view and
the next k - 1 views of the ``spread`` order (:func:`nbv.geometry.viewspace.spread_views`: each
view farthest in angle from those before, ties broken by ``named_rng(seed, key, start)``).

Command: ``python -m nbv.eval.completion_quality dataset=<folder> viewspace=original
checkpoint=<file> out=<folder> [models=unseen|test|all] [seed=0]`` writes ``quality.csv`` (one
row per model, start view and k) and ``quality.md`` (:func:`summarise`).
"""

from __future__ import annotations

import csv
import io
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from scipy.spatial import cKDTree
from tqdm import tqdm

from nbv.geometry.clouds import near
from nbv.geometry.viewspace import spread_views, unit_directions
from nbv.utils.markdown import md_table
from nbv.utils.seeding import named_rng
from nbv.utils.stats import Interval, bootstrap_mean

#: The F-score threshold (normalised frame).
F_THRESHOLD = 0.01
#: The start views of every model.
STARTS = (1, 7, 15, 27)
#: The clouds compared: the partial cloud, its mirror completion, the network's output, and the
#: completed cloud ("union"): the partial cloud and the predicted points farther than the
#: completer's ``fill`` from it (:func:`nbv.geometry.clouds.fill_in`).
KINDS = ("partial", "mirror", "network", "union")
#: Mirror planes through the origin: 12 vertical (normal (cos a, 0, sin a), a = 0, 15, ...,
#: 165 degrees), then the horizontal y = 0.
MIRROR_NORMALS = np.array(
    [[np.cos(a), 0.0, np.sin(a)] for a in np.radians(np.arange(0, 180, 15))] + [[0.0, 1.0, 0.0]]
)


class Completion(Protocol):
    def batch(self, clouds: list[np.ndarray]) -> np.ndarray: ...


def _cloud(points: np.ndarray, name: str) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
        raise ValueError(f"{name}: a (N, 3) cloud with N >= 1 expected, got shape {p.shape}")
    return p


def _nearest(a: np.ndarray, tree: cKDTree) -> np.ndarray:
    """(N,) Euclidean distance from each point of ``a`` to the tree's nearest point."""
    return tree.query(a, k=1)[0]


def _scores(d_pred: np.ndarray, d_gt: np.ndarray, d: float) -> tuple[float, float]:
    """(CD-L1, F-score at ``d``) from the two sides' nearest distances."""
    precision, recall = float(np.mean(d_pred < d)), float(np.mean(d_gt < d))
    f = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    return (float(d_pred.mean()) + float(d_gt.mean())) / 2, f


def _sides(pred: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p, g = _cloud(pred, "pred"), _cloud(gt, "gt")
    return _nearest(p, cKDTree(g)), _nearest(g, cKDTree(p))


def fscore(pred: np.ndarray, gt: np.ndarray, d: float = F_THRESHOLD) -> float:
    """F-score at threshold ``d``: the harmonic mean of precision (share of ``pred`` (N, 3)
    closer than ``d`` to ``gt`` (M, 3)) and recall (share of ``gt`` closer than ``d`` to
    ``pred``); 0 when both are 0. Float64, cloud units."""
    return _scores(*_sides(pred, gt), d)[1]


def cd_l1(pred: np.ndarray, gt: np.ndarray) -> float:
    """CD-L1 between ``pred`` (N, 3) and ``gt`` (M, 3): ``(mean_pred d(pred, gt) + mean_gt
    d(gt, pred)) / 2`` with Euclidean nearest distances, cloud units (as
    :func:`nbv.models.completion.chamfer_l1`)."""
    return _scores(*_sides(pred, gt), 0.0)[0]


def _reflect(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    return points - 2.0 * (points @ normal)[:, None] * normal


def _best_mirror(
    partial: np.ndarray, gt: np.ndarray, gt_tree: cKDTree
) -> tuple[int, np.ndarray, np.ndarray]:
    """The index in :data:`MIRROR_NORMALS` of the plane whose completion of ``partial`` (N, 3)
    is closest to ``gt`` (M, 3) (CD-L1), with the (2N,) nearest distances of that completion to
    ``gt`` and the (M,) ones of ``gt`` to it.

    A reflection is an isometry: d(g, R p) = d(R g, p), so one tree of ``partial`` serves
    every plane."""
    tree = cKDTree(partial)
    d_p, d_g = _nearest(partial, gt_tree), _nearest(gt, tree)
    sides = [
        (np.concatenate([d_p, _nearest(_reflect(partial, n), gt_tree)]),
         np.minimum(d_g, _nearest(_reflect(gt, n), tree)))
        for n in MIRROR_NORMALS
    ]  # fmt: skip
    i = int(np.argmin([_scores(d_pred, d_gt, 0.0)[0] for d_pred, d_gt in sides]))
    return i, *sides[i]


def mirror_completion(partial: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """``partial`` (N, 3) and its reflection in the plane of :data:`MIRROR_NORMALS` that gives
    the lowest CD-L1 to ``gt`` (M, 3): (2N, 3) float32.

    The plane is chosen by looking at the ground truth (an oracle): this is the strongest
    mirror-symmetry baseline, an upper bound on what a symmetry prior alone could give."""
    p, g = _cloud(partial, "partial"), _cloud(gt, "gt")
    i = _best_mirror(p, g, cKDTree(g))[0]
    return np.concatenate([p, _reflect(p, MIRROR_NORMALS[i])]).astype(np.float32)


def view_order(
    positions: np.ndarray, start: int, count: int, rng: np.random.Generator
) -> list[int]:
    """``start`` then ``count - 1`` views of the spread order from the (V, 3) camera positions."""
    closed = np.zeros(len(positions), dtype=bool)
    closed[start] = True
    return [start, *spread_views(unit_directions(positions), closed, count - 1, rng)]


def quality_rows(
    dataset: Any,
    keys: Sequence[str],
    viewspace: str,
    completer: Completion,
    views_list: Sequence[int] = (1, 2, 3, 4, 5),
    starts: Sequence[int] = STARTS,
    seed: int = 0,
    progress: bool = False,
) -> list[dict]:
    """One row per model of ``keys``, start view and k of ``views_list``.

    ``dataset.model(key)`` gives ``.category``, ``.gt_points`` (M, 3) and ``.captured(viewspace)``
    (``.poses`` (V, 4, 4), ``.view_points(v)`` (N_v, 3)). A row holds ``key, category, start, k,
    views`` (space-separated), ``n_points`` (of the partial cloud), ``plane`` (the mirror's index
    in :data:`MIRROR_NORMALS`) and ``cd_<kind>``, ``f_<kind>`` for each of :data:`KINDS`
    (CD-L1 and F-score at :data:`F_THRESHOLD` against ``gt_points``, normalised frame).

    Raises:
        ValueError: a captured cloud without points (model, start and k named).
    """
    rows: list[dict] = []
    for key in tqdm(keys, desc="completion quality", unit="model", disable=not progress):
        model = dataset.model(key)
        gt = _cloud(model.gt_points, f"{key}: gt_points")
        gt_tree = cKDTree(gt)
        cap = model.captured(viewspace)
        cases, clouds = [], []
        for start in starts:
            order = view_order(
                cap.poses[:, :3, 3], start, max(views_list), named_rng(seed, key, start)
            )
            for k in views_list:
                cloud = np.concatenate([cap.view_points(v) for v in order[:k]])
                if len(cloud) == 0:
                    raise ValueError(f"{key}: start {start}, {k} views: no captured points")
                cases.append((start, k, order[:k]))
                clouds.append(cloud.astype(np.float64))
        outputs = np.asarray(completer.batch(clouds), dtype=np.float64)
        fill = float(getattr(completer, "fill", 0.0))
        for (start, k, views), partial, net in zip(cases, clouds, outputs, strict=True):
            plane, *d_mirror = _best_mirror(partial, gt, gt_tree)
            row = {"key": key, "category": model.category, "start": start, "k": k,
                   "views": " ".join(map(str, views)), "n_points": len(partial),
                   "plane": plane}  # fmt: skip
            d_part_gt, d_net_gt = _nearest(partial, gt_tree), _nearest(net, gt_tree)
            d_gt_part, d_gt_net = _nearest(gt, cKDTree(partial)), _nearest(gt, cKDTree(net))
            # The completed cloud: the capture and the predictions it lacks (fill_in).
            far = ~near(partial, net, fill)
            d_gt_net_far = (
                _nearest(gt, cKDTree(net[far])) if far.any() else np.full(len(gt), np.inf)
            )
            sides = {
                "partial": (d_part_gt, d_gt_part),
                "mirror": tuple(d_mirror),
                "network": (d_net_gt, d_gt_net),
                "union": (
                    np.concatenate([d_part_gt, d_net_gt[far]]),
                    np.minimum(d_gt_part, d_gt_net_far),
                ),
            }
            for kind, (d_pred, d_gt) in sides.items():
                row[f"cd_{kind}"], row[f"f_{kind}"] = _scores(d_pred, d_gt, F_THRESHOLD)
            rows.append(row)
    return rows


@dataclass(frozen=True)
class KSummary:
    """The rows of one k: ``means`` of ``cd_<kind>`` / ``f_<kind>`` over models (start views
    averaged within a model first), and ``diffs`` ``<metric>_union-partial`` and
    ``<metric>_union-mirror``: paired per-model differences with 95 % bootstrap intervals."""

    k: int
    models: int
    means: dict[str, float]
    diffs: dict[str, Interval]


def summarise(rows: list[dict], seed: int = 0) -> list[KSummary]:
    """One :class:`KSummary` per k of ``rows`` (of :func:`quality_rows`), k ascending."""
    out = []
    columns = [f"{m}_{kind}" for m in ("cd", "f") for kind in KINDS]
    for k in sorted({r["k"] for r in rows}):
        of_k = [r for r in rows if r["k"] == k]
        keys = list(dict.fromkeys(r["key"] for r in of_k))
        per = {c: np.array([np.mean([r[c] for r in of_k if r["key"] == key]) for key in keys])
               for c in columns}  # fmt: skip
        diffs = {f"{m}_union-{b}": bootstrap_mean(per[f"{m}_union"] - per[f"{m}_{b}"], seed=seed)
                 for m in ("cd", "f") for b in ("partial", "mirror")}  # fmt: skip
        out.append(KSummary(k, len(keys), {c: float(v.mean()) for c, v in per.items()}, diffs))
    return out


def summary_markdown(summary: list[KSummary], title: str) -> str:
    """The Markdown page of :func:`summarise`: one table for CD-L1, one for the F-score."""
    lines = [f"# {title}", ""]
    for m, name, digits in (("cd", "CD-L1, normalised frame (radius 0.5)", 4),
                            ("f", f"F-score at d = {F_THRESHOLD}", 3)):  # fmt: skip
        lines += [f"## {name}", "", "Means over models (start views averaged within a model); "
                  "differences paired by model, 95 % bootstrap intervals.", ""]  # fmt: skip
        header = ["k", "models", *KINDS, "union - partial", "union - mirror"]
        body = [
            [str(s.k), str(s.models), *(f"{s.means[f'{m}_{kind}']:.{digits}f}" for kind in KINDS),
             s.diffs[f"{m}_union-partial"].text(digits), s.diffs[f"{m}_union-mirror"].text(digits)]
            for s in summary
        ]  # fmt: skip
        lines += [*md_table(header, body), ""]
    return "\n".join(lines)


def rows_csv(rows: list[dict]) -> str:
    """``rows`` as CSV text (the first row's columns)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def _arguments(argv: Sequence[str], defaults: dict[str, str]) -> dict[str, str]:
    """``key=value`` items over ``defaults``; ValueError for an unknown key or a missing ``=``."""
    args = dict(defaults)
    for item in argv:
        key, sep, value = item.partition("=")
        if not sep or key not in args:
            raise ValueError(f"bad argument {item!r}; allowed: {'=, '.join(args)}=")
        args[key] = value
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """The command (see the module's docstring); 2 with one line on stderr for a bad argument,
    before any work and writing nothing."""
    from nbv.assets.categories import TRAIN_CATEGORIES, UNSEEN_CATEGORIES
    from nbv.assets.weights import FOLDER
    from nbv.dataset.reader import open_dataset
    from nbv.models.completion_inference import Completer
    from nbv.scan.shipped import COMPLETION_WEIGHTS
    from nbv.utils.atomic import write_text

    defaults = {"dataset": "data/generated/synthetic", "viewspace": "original", "out": "",
                "checkpoint": str(FOLDER / f"{COMPLETION_WEIGHTS}.pt"), "models": "unseen",
                "seed": "0"}  # fmt: skip
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv in (["--help"], ["-h"]):
        print(__doc__)
        return 0
    try:
        a = _arguments(argv, defaults)
        wanted = {"unseen": UNSEEN_CATEGORIES, "test": TRAIN_CATEGORIES, "all": None}
        if not a["out"]:
            raise ValueError("out=<folder> is required")
        if a["models"] not in wanted or not a["seed"].isdigit():
            raise ValueError(f"models={a['models']!r} (unseen, test, all), seed={a['seed']!r}")
        ds = open_dataset(a["dataset"])
        if a["viewspace"] not in ds.viewspaces:
            raise ValueError(f"viewspace={a['viewspace']!r}; allowed: {', '.join(ds.viewspaces)}")
        cats = wanted[a["models"]]
        keys = [k for k in ds.keys(split=None if cats is None else "test")
                if cats is None or ds.index[k][1] in cats]  # fmt: skip
        if not keys:
            raise ValueError(f"dataset={a['dataset']}: no models for models={a['models']}")
        completer = Completer.from_checkpoint(a["checkpoint"])
    except ValueError as err:
        print(f"completion_quality: {err}", file=sys.stderr)
        return 2
    seed, out = int(a["seed"]), Path(a["out"])
    rows = quality_rows(ds, keys, a["viewspace"], completer, seed=seed, progress=True)
    title = (f"Completion quality: {a['dataset']} ({a['models']}, {len(keys)} models), "
             f"viewspace {a['viewspace']}, checkpoint {a['checkpoint']}")  # fmt: skip
    write_text(out / "quality.csv", rows_csv(rows))
    write_text(out / "quality.md", summary_markdown(summarise(rows, seed), title))
    print(f"completion_quality: wrote {out / 'quality.csv'} and {out / 'quality.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
