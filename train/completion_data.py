"""The completion network's data: partial views and true surfaces of the training categories.

Every model of the synthetic training categories (never an unseen one) is ray cast from
``VIEW_GROUPS``: the original viewspace (33 views), the permuted one (33), and ``n_random``
directions drawn uniformly on the sphere for that model, so that the network does not learn one
viewspace's layout. Each view keeps ``points_per_view`` of its back-projected points (a seeded
random subset), and each model its true surface: ``n_gt`` points farthest-point sampled from
16,384 drawn uniformly by area. Points are stored as float16 in the dataset's normalised frame
(the object within radius 0.5 of the origin; float16 keeps them to 2.4e-4).

The views are ray cast with the dataset's field of view at a quarter of its resolution
(:data:`CAMERA`): a view of an object still holds thousands of pixels, more than the points kept.

Shards (``shard-KKKKK-of-NNNNN.h5``, model ``i`` in shard ``i % N``) are written whole to a
temporary name and renamed when done, so a killed run leaves complete shards only and a rerun
makes the missing ones. A shard's attributes record the settings it was made with; a shard made
with other settings is refused, never mixed.

A sample (:func:`draw_sample`): one model, one view group, 1 to 5 of its views; the input is the
union of their points farthest-point sampled to the network's input size.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from nbv.assets.categories import TRAIN_CATEGORIES
from nbv.assets.meshes import sample_surface
from nbv.dataset.schema import hdf5_written
from nbv.dataset.sources import SourceModel, list_models, load_normalised
from nbv.geometry.camera import Intrinsics, backproject, valid_depth, viewspace_poses
from nbv.geometry.clouds import farthest_points
from nbv.geometry.raycast import raycast_depth
from nbv.geometry.viewspace import get_viewspace
from nbv.utils.artefacts import check_array, reading
from nbv.utils.seeding import named_rng

#: The dataset camera's field of view (640 x 480, f = 476) at a quarter of its resolution.
CAMERA = Intrinsics.centred(160, 120, 119.0)
#: The view groups of a model, in the order its views are stored.
VIEW_GROUPS = ("original", "permuted", "random")
#: Version of the shard layout.
LAYOUT = 1


#: What a shard of this data is, in a refusal.
SHARD = "completion data shard"


class CompletionDataError(ValueError):
    """A completion data folder or shard that cannot be used (the message names it)."""


@dataclass(frozen=True)
class DataSettings:
    """How the completion data is made (every field changes the shards' bytes).

    Attributes:
        train_models: models of each training category's train split.
        valid_models: models of each training category's valid split (the validation set).
        n_random: random directions per model.
        points_per_view: points kept of each view.
        n_gt: points of the stored true surface.
        seed: the synthetic models' seed (the dataset's), and the draws' here.
        shards: number of shards.
    """

    train_models: int = 125
    valid_models: int = 4
    n_random: int = 16
    points_per_view: int = 512
    n_gt: int = 2048
    seed: int = 0
    shards: int = 8


def shard_name(shard: int, shards: int) -> str:
    """The file name of shard ``shard`` of ``shards``."""
    return f"shard-{shard:05d}-of-{shards:05d}.h5"


def models(settings: DataSettings) -> list[SourceModel]:
    """The synthetic models of the training categories: one test model per category is left
    out (the default dataset's test model of that index), then ``valid_models`` and
    ``train_models``."""
    counts = {"train": settings.train_models, "valid": settings.valid_models, "test": 1,
              "unseen": 0}  # fmt: skip
    return [
        m
        for m in list_models("synthetic", counts=counts, seed=settings.seed)
        if m.category in TRAIN_CATEGORIES and m.split != "test"
    ]


def view_directions(key: str, settings: DataSettings) -> np.ndarray:
    """(33 + 33 + n_random, 3) float64 unit directions of a model's views (:data:`VIEW_GROUPS`
    in order); the random ones are seeded by the model's key."""
    rng = named_rng(settings.seed, "completion-directions", key)
    random = rng.normal(size=(settings.n_random, 3))
    random /= np.linalg.norm(random, axis=1, keepdims=True)
    return np.concatenate([get_viewspace("original"), get_viewspace("permuted"), random])


def group_slices(settings: DataSettings) -> dict[str, slice]:
    """Each view group's rows of :func:`view_directions`."""
    return {"original": slice(0, 33), "permuted": slice(33, 66),
            "random": slice(66, 66 + settings.n_random)}  # fmt: skip


def model_record(model: SourceModel, settings: DataSettings) -> dict[str, np.ndarray]:
    """One model's arrays: ``points`` (V * points_per_view, 3) float16 (a view with fewer
    points repeats them; a view that sees nothing is all NaN), ``counts`` (V,) int32 the
    distinct points each view kept, ``gt`` (n_gt, 3) float16."""
    mesh, _, _ = load_normalised(model, settings.seed)
    rng = named_rng(settings.seed, "completion", model.key)
    gt = farthest_points(sample_surface(mesh, 16384, rng).astype(np.float64), settings.n_gt)
    poses = viewspace_poses(view_directions(model.key, settings))
    depth = raycast_depth(mesh.vertices, mesh.faces, poses, CAMERA, threads=1)
    k = settings.points_per_view
    points = np.full((len(poses), k, 3), np.nan, dtype=np.float32)
    counts = np.zeros(len(poses), dtype=np.int32)
    for v, (image, pose) in enumerate(zip(depth, poses, strict=True)):
        pts = backproject(image, CAMERA, pose, valid_depth(image))
        if len(pts) == 0:
            continue
        keep = rng.choice(len(pts), min(k, len(pts)), replace=False)
        counts[v] = len(keep)
        points[v] = pts[np.sort(keep)][np.arange(k) % len(keep)]
    return {"points": points.reshape(-1, 3).astype(np.float16), "counts": counts,
            "gt": gt.astype(np.float16)}  # fmt: skip


def _attrs(settings: DataSettings) -> dict:
    return {"layout": LAYOUT, "settings": json.dumps(asdict(settings), sort_keys=True)}


def make_shards(out_dir: Path, settings: DataSettings, progress: bool = True) -> list[Path]:
    """Make the shards missing from ``out_dir`` (see the module docstring); return every shard.

    Raises:
        CompletionDataError: a shard there was made with other settings.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    everything = models(settings)
    paths = []
    for shard in range(settings.shards):
        path = out_dir / shard_name(shard, settings.shards)
        paths.append(path)
        if path.exists():
            check_shard(path, settings)
            continue
        mine = everything[shard :: settings.shards]
        with hdf5_written(path) as f:
            f.attrs.update(_attrs(settings))
            for model in tqdm(mine, desc=path.name, unit="model", disable=not progress):
                group = f.create_group(model.key)
                group.attrs.update({"category": model.category, "split": model.split})
                for name, array in model_record(model, settings).items():
                    group.create_dataset(name, data=array)
    return paths


def check_shard(path: Path, settings: DataSettings) -> None:
    """Refuse a shard that is not a readable completion shard of ``settings``.

    Raises:
        CompletionDataError: one line naming the file and what differs.
    """
    with reading(path, SHARD), h5py.File(path, "r") as f:
        attrs = dict(f.attrs)
    if attrs.get("layout") != LAYOUT:
        raise CompletionDataError(f"{path}: layout {attrs.get('layout')!r}, expected {LAYOUT}")
    if attrs.get("settings") != _attrs(settings)["settings"]:
        raise CompletionDataError(
            f"{path}: made with other settings ({attrs.get('settings')}); expected "
            f"{_attrs(settings)['settings']}: use another data_dir, or delete it"
        )


@dataclass
class CompletionData:
    """Every model's views and true surface, in memory.

    Attributes:
        keys: model keys, shard after shard.
        split: (M,) the split of each model ("train" or "valid").
        category: (M,) category names.
        points: (M, V, points_per_view, 3) float16.
        counts: (M, V) int32 distinct points of each view (0: the view saw nothing).
        gt: (M, n_gt, 3) float16.
        groups: view group -> its slice of the views.
    """

    keys: list[str]
    split: np.ndarray
    category: np.ndarray
    points: np.ndarray
    counts: np.ndarray
    gt: np.ndarray
    groups: dict[str, slice]

    def subset(self, split: str) -> np.ndarray:
        """Indices of the models of ``split``."""
        return np.flatnonzero(self.split == split)


def load(paths: list[Path], settings: DataSettings) -> CompletionData:
    """Every model of the shards ``paths`` (each checked by :func:`check_shard`)."""
    keys, split, category, points, counts, gt = [], [], [], [], [], []
    k = settings.points_per_view
    views = group_slices(settings)["random"].stop
    for path in paths:
        check_shard(path, settings)
        with reading(path, SHARD), h5py.File(path, "r") as f:
            for key in f:
                g = f[key]
                keys.append(key)
                split.append(str(g.attrs["split"]))
                category.append(str(g.attrs["category"]))
                # A view that saw nothing is all NaN (model_record): shapes only here.
                cloud = check_array(g["points"][()], path, f"{key}/points", (views * k, 3),
                                    finite=False)  # fmt: skip
                points.append(cloud.reshape(views, k, 3))
                counts.append(check_array(g["counts"][()], path, f"{key}/counts", (views,)))
                gt.append(check_array(g["gt"][()], path, f"{key}/gt", (settings.n_gt, 3)))
    return CompletionData(keys, np.array(split), np.array(category), np.stack(points),
                          np.stack(counts), np.stack(gt), group_slices(settings))  # fmt: skip


def draw_sample(
    data: CompletionData, model: int, rng: np.random.Generator, n_input: int, max_views: int = 5
) -> tuple[np.ndarray, int]:
    """One input cloud of ``model``: a view group, 1 to ``max_views`` of its views that saw the
    object, their points' union farthest-point sampled to ``n_input`` (float32 (n_input, 3)),
    and the number of views."""
    group = list(data.groups.values())[rng.integers(len(data.groups))]
    seen = np.arange(group.start, group.stop)[data.counts[model, group] > 0]
    k = int(rng.integers(1, max_views + 1))
    views = rng.choice(seen, min(k, len(seen)), replace=False)
    cloud = np.concatenate([data.points[model, v, : data.counts[model, v]] for v in views]).astype(
        np.float32
    )
    return farthest_points(cloud, n_input), len(views)


def fixed_samples(
    data: CompletionData, indices: np.ndarray, seed: int, n_input: int, per_model: int
) -> Iterator[tuple[int, np.ndarray, int]]:
    """``per_model`` seeded samples of each model of ``indices`` (the validation set: the same
    samples at every epoch): ``(model, input, views)``."""
    for m in indices:
        rng = named_rng(seed, "completion-valid", int(m))
        for _ in range(per_model):
            cloud, views = draw_sample(data, int(m), rng, n_input)
            yield int(m), cloud, views
