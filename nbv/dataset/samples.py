"""Training samples: oracle trajectories over a model's views, as PC-NBV's networks learn them.

For each model and each of ``trajectories`` seeded random start views, a trajectory visits
``steps`` views: the start view, then at each step the unvisited view with the largest true gain of
the chosen score (the oracle), or with probability ``random_step_prob`` a random unvisited view, so
that the samples also hold states the oracle would not visit. Before each pick a sample is stored:

* ``points``: the accumulated cloud of the visited views reduced by farthest point sampling to
  ``n_points`` points,
* ``view_state``: (V,) bool, the visited views,
* ``target``: (V,) the gain each view would add to the score (0 for visited views),
* ``signature``: the spherical-harmonics signature (:func:`nbv.geometry.sph.signature`) of the
accumulated
  cloud at ``lmax``,
* ``value``: the score of the state itself.

Scores: ``coverage`` (from the dataset's per-view coverage bits, i.e. of the full-resolution views)
and ``vig`` (from the per-view hull vertices, exact). Models whose ground-truth hull has no volume
are skipped for ``vig`` and listed in ``/skipped``.

File ``samples-shard-SSSSS-of-NNNNN.h5`` beside each dataset shard::

    / (attrs)                 schema_version, viewspace, n_views, n_points, lmax, trajectories,
                              steps, random_step_prob, seed, dataset (the shard file's name),
                              dataset_eps (the shard's eps: the targets' coverage criterion)
    /models/key, category, split      (M,) strings
    /skipped                  (K, 3) strings: key, score, reason
    /<score>/points           (S, n_points, 3) float32
    /<score>/signature        (S, 4 (lmax + 1)^2, 3) float32, in the cloud's own frame
    /<score>/view_state       (S, V) bool
    /<score>/target           (S, V) float32
    /<score>/value            (S,) float32
    /<score>/model            (S,) int32, row of /models
    /<score>/trajectory, step (S,) int16
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from nbv.dataset.reader import SHARD, Dataset, DatasetError, shard_files
from nbv.dataset.records import SCORES, ModelData, score_functions
from nbv.dataset.schema import hdf5_written, write_strings
from nbv.geometry.clouds import farthest_points
from nbv.geometry.hull import QhullFailure
from nbv.geometry.sph import signature
from nbv.utils.artefacts import ArtefactError, check_array, reading
from nbv.utils.lock import one_writer
from nbv.utils.seeding import named_rng
from nbv.utils.selection import masked_argmax

SCHEMA_VERSION = 1


@dataclass(frozen=True)
class SampleSettings:
    """How samples are drawn (``samples:`` in ``conf/dataset.yaml``, whose ``seed`` is the
    dataset's). Stored as the samples file's attributes: a file made with other settings is
    rewritten.

    Attributes:
        trajectories: random start views per model (>= 1).
        steps: views visited per trajectory, one sample per state (>= 1).
        n_points: farthest-point-sampled points per sample cloud (>= 1).
        lmax: the spherical-harmonics degree of the signature (>= 0).
        random_step_prob: probability that a step takes a random unvisited view instead of the
            oracle's best, in [0, 1].
        scores: the scores to sample: ``coverage`` and/or ``vig``.
        viewspace: the dataset viewspace the trajectories walk.
        seed: the seed of the start views and random steps.
    """

    trajectories: int = 4
    steps: int = 10
    n_points: int = 1024
    lmax: int = 3
    random_step_prob: float = 0.0
    scores: tuple[str, ...] = SCORES
    viewspace: str = "original"
    seed: int = 0

    def __post_init__(self) -> None:
        bad = [s for s in self.scores if s not in SCORES]
        if bad:
            raise ValueError(f"samples.scores: unknown {bad}; allowed: {', '.join(SCORES)}")
        if not 0.0 <= self.random_step_prob <= 1.0:
            raise ValueError(f"samples.random_step_prob={self.random_step_prob}: must be in [0, 1]")
        if self.trajectories < 1 or self.steps < 1 or self.n_points < 1 or self.lmax < 0:
            raise ValueError(
                "samples.trajectories, steps and n_points must be >= 1 and lmax >= 0, got "
                f"{self.trajectories}, {self.steps}, {self.n_points}, {self.lmax}"
            )


def walk(
    gains: Callable[[np.ndarray], np.ndarray],
    n_views: int,
    start: int,
    steps: int,
    rng: np.random.Generator,
    random_step_prob: float = 0.0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """One trajectory: (view_state, gains) before each pick, ``steps`` states in all.

    Args:
        gains: view_state (V,) bool -> (V,) gain of adding each view (0 for visited ones).
        n_views: V.
        start: the first visited view.
        steps: number of visited views at the last state.
        rng: generator of the random steps.
        random_step_prob: probability of a random unvisited view instead of the best one.

    Returns:
        ``steps`` pairs; state ``i`` has ``i + 1`` visited views.
    """
    state = np.zeros(n_views, dtype=bool)
    state[start] = True
    out = []
    for _ in range(steps):
        g = gains(state)
        out.append((state.copy(), g))
        if state.all():
            break
        if random_step_prob > 0 and rng.random() < random_step_prob:
            nxt = int(rng.choice(np.flatnonzero(~state)))
        else:
            nxt = masked_argmax(g, state)
        state[nxt] = True
    return out


def model_samples(model: ModelData, score: str, settings: SampleSettings) -> dict[str, np.ndarray]:
    """All samples of one model for one score (see the module docstring), as arrays."""
    view = model.views[settings.viewspace]
    n_views = len(view.poses)
    rng = named_rng(settings.seed, f"{model.key}/{score}")
    # A trajectory starts where the object is seen (a flat object seen edge-on shows nothing).
    seen = np.flatnonzero(np.diff(view.offsets) > 0)
    starts = rng.choice(seen, size=min(settings.trajectories, len(seen)), replace=False)
    gains, value = score_functions(model, score, settings.viewspace)
    rows: dict[str, list] = {k: [] for k in ("points", "signature", "view_state", "target")}
    rows.update(value=[], trajectory=[], step=[])
    for t, start in enumerate(starts):
        for step, (state, g) in enumerate(
            walk(gains, n_views, int(start), settings.steps, rng, settings.random_step_prob)
        ):
            cloud = np.concatenate([view.view_points(v) for v in np.flatnonzero(state)])
            rows["points"].append(farthest_points(cloud, settings.n_points))
            rows["signature"].append(signature(cloud, settings.lmax))
            rows["view_state"].append(state)
            rows["target"].append(g)
            rows["value"].append(value(state))
            rows["trajectory"].append(t)
            rows["step"].append(step)
    dtypes = dict(
        points=np.float32, signature=np.float32, view_state=bool, target=np.float32,
        value=np.float32, trajectory=np.int16, step=np.int16,
    )  # fmt: skip
    return {k: np.asarray(v, dtype=dtypes[k]) for k, v in rows.items()}


def samples_path(shard_file: Path) -> Path:
    """The samples file beside a dataset shard file."""
    return shard_file.with_name("samples-" + shard_file.name)


def _model_job(args: tuple[Path, str, SampleSettings]) -> tuple[dict, list]:
    """All scores' samples of one model (run in a worker process): ({score: arrays}, skipped)."""
    shard_file, key, settings = args
    model = Dataset([shard_file]).model(key, (settings.viewspace,))
    arrays, skipped = {}, []
    for score in settings.scores:
        if score == "vig" and model.gt_hull_error:
            skipped.append((key, score, f"Qhull failed on the ground truth: {model.gt_hull_error}"))
        elif score == "vig" and not model.gt_hull_volume > 0:
            skipped.append((key, score, "ground-truth hull has no volume: VIG undefined"))
        else:
            try:
                arrays[score] = model_samples(model, score, settings)
            except QhullFailure as err:  # a union of views Qhull refused: no made-up gains
                skipped.append((key, score, str(err)))
    return arrays, skipped


def write_samples(
    shard_file: Path, settings: SampleSettings, progress: bool = True, workers: int = 0
) -> tuple[Path, list[tuple[str, str, str]]]:
    """Compute every sample of one dataset shard and write its samples file atomically.

    Args:
        shard_file: the dataset shard.
        settings: how to draw the samples.
        progress: show a progress bar over models.
        workers: processes computing models in parallel (0 = one per CPU core, 1 = this one).
            The result does not depend on it: every model has its own seeded generator.

    Returns:
        The samples file and the (key, score, reason) of skipped model/score pairs.

    Raises:
        OutputBusy: another process is writing this samples file.
    """
    with one_writer(samples_path(shard_file), "samples file"):
        return _write_samples(shard_file, settings, progress, workers)


def _write_samples(
    shard_file: Path, settings: SampleSettings, progress: bool, workers: int
) -> tuple[Path, list[tuple[str, str, str]]]:
    """:func:`write_samples`' work, under the samples file's lock."""
    dataset = Dataset([shard_file])
    if settings.viewspace not in dataset.viewspaces:
        raise DatasetError(
            f"{shard_file}: samples.viewspace={settings.viewspace!r} not in the dataset "
            f"({sorted(dataset.viewspaces)})"
        )
    keys = list(dataset)
    collected: dict[str, list[dict]] = {s: [] for s in settings.scores}
    skipped: list[tuple[str, str, str]] = []
    jobs = [(shard_file, key, settings) for key in keys]
    workers = min(workers or os.cpu_count() or 1, len(keys))
    with contextlib.ExitStack() as stack:
        if workers > 1:
            pool = stack.enter_context(ProcessPoolExecutor(workers, mp.get_context("fork")))
            results = pool.map(_model_job, jobs)
        else:
            results = map(_model_job, jobs)
        bar = tqdm(results, total=len(keys), desc="samples", unit="model", disable=not progress)
        for index, (arrays, skip) in enumerate(bar):
            skipped += skip
            for score, a in arrays.items():
                a["model"] = np.full(len(a["step"]), index, dtype=np.int32)
                collected[score].append(a)
    out = samples_path(shard_file)
    with hdf5_written(out) as handle:
        attrs = asdict(settings)
        attrs["scores"] = list(settings.scores)
        handle.attrs.update(attrs)
        handle.attrs.update(
            schema_version=SCHEMA_VERSION,
            dataset=shard_file.name,
            # The targets come from the shard's coverage bits: a shard remade with another
            # eps makes these samples stale (samples_up_to_date, load_samples).
            dataset_eps=float(dataset.attrs["eps"]),
            n_views=len(dataset.viewspaces[settings.viewspace]),
        )
        write_strings(handle, "models/key", keys)
        write_strings(handle, "models/category", [dataset.index[k][1] for k in keys])
        write_strings(handle, "models/split", [dataset.index[k][2] for k in keys])
        write_strings(handle, "skipped", [list(s) for s in skipped], columns=3)
        for score, parts in collected.items():
            group = handle.create_group(score)
            if not parts:
                continue
            for name in parts[0]:
                data = np.concatenate([p[name] for p in parts])
                group.create_dataset(name, data=data, compression="gzip", shuffle=True)
    return out, skipped


def samples_up_to_date(shard_file: Path, settings: SampleSettings) -> bool:
    """True when the samples file beside ``shard_file`` holds this shard's models and settings."""
    out = samples_path(shard_file)
    if not out.exists():
        return False
    with h5py.File(out, "r") as handle, h5py.File(shard_file, "r") as shard:
        same_models = list(handle["models/key"].asstr()[()]) == list(shard.get("models", {}))
        stored = {k: handle.attrs.get(k) for k in asdict(settings)}
        # A file from before dataset_eps was recorded is remade: its eps is unknown.
        same_eps = handle.attrs.get("dataset_eps") == shard.attrs["eps"]
    wanted = asdict(settings)
    same_settings = all(
        np.array_equal(np.asarray(stored[k]), np.asarray(v)) for k, v in wanted.items()
    )
    return same_models and same_settings and bool(same_eps)


@dataclass
class SampleSet:
    """The samples of one score over every shard of a dataset, in memory.

    Attributes:
        points, signature, view_state, target, value, trajectory, step: stacked arrays (S, ...).
        key, category, split: (S,) per-sample model key, category and split (str arrays).
        attrs: the samples files' settings.
    """

    points: np.ndarray
    signature: np.ndarray
    view_state: np.ndarray
    target: np.ndarray
    value: np.ndarray
    trajectory: np.ndarray
    step: np.ndarray
    key: np.ndarray
    category: np.ndarray
    split: np.ndarray
    attrs: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.step)

    def select(self, mask: np.ndarray) -> SampleSet:
        """The samples where ``mask`` (S,) is True."""
        arrays = {k: v[mask] for k, v in vars(self).items() if isinstance(v, np.ndarray)}
        return SampleSet(**arrays, attrs=self.attrs)


#: The arrays of one score's samples, in a samples file's ``/<score>/`` group.
SAMPLE_ARRAYS = ("model", "points", "signature", "view_state", "target", "value", "trajectory",
                 "step")  # fmt: skip
#: What a samples file is, in a refusal.
SAMPLES = "samples file"


def _check_samples(file: Path, score: str, arrays: dict[str, np.ndarray], n_models: int) -> None:
    """Refuse a score's samples whose arrays disagree in length or shape, hold NaN or name a
    model the file does not list."""
    n = len(arrays["step"])
    views = arrays["view_state"].shape[1] if arrays["view_state"].ndim == 2 else None
    shapes = {"model": (n,), "points": (n, None, 3), "signature": (n, None, 3),
              "view_state": (n, views), "target": (n, views), "value": (n,),
              "trajectory": (n,), "step": (n,)}  # fmt: skip
    for name, shape in shapes.items():
        check_array(arrays[name], file, f"{score}/{name}", shape)
    if n and (arrays["model"].min() < 0 or arrays["model"].max() >= n_models):
        raise ArtefactError(file, f"{score}/model names models outside the {n_models} listed")


def _check_samples_eps(shard_file: Path, file: Path) -> None:
    """Refuse samples whose targets were computed from a shard made with another eps."""
    with reading(file, SAMPLES), h5py.File(file, "r") as handle:
        made = handle.attrs.get("dataset_eps")
    with reading(shard_file, SHARD), h5py.File(shard_file, "r") as shard:
        now = float(shard.attrs["eps"])
    # Files from before dataset_eps was recorded carry no eps to compare.
    if made is not None and float(made) != now:
        raise DatasetError(
            f"{file}: samples made from a shard with eps={float(made)!r}, but {shard_file} has "
            f"eps={now!r}; remake them (make dataset, samples stage)"
        )


def load_samples(path: str | Path, score: str) -> SampleSet:
    """Read one score's samples from a dataset folder (or one samples file)."""
    if score not in SCORES:
        raise ValueError(f"score={score!r}: must be one of {', '.join(SCORES)}")
    path = Path(path)
    shards = [] if path.is_file() else shard_files(path)
    files = [path] if path.is_file() else [samples_path(f) for f in shards]
    missing = [str(f) for f in files if not f.exists()]
    if missing:
        raise DatasetError(f"no samples file {missing[0]}; run `make dataset` (samples stage)")
    for shard, file in zip(shards, files, strict=True):
        _check_samples_eps(shard, file)
    parts: dict[str, list] = {}
    attrs: dict = {}
    for file in files:
        with reading(file, SAMPLES), h5py.File(file, "r") as handle:
            if "models" not in handle or "schema_version" not in handle.attrs:
                raise ArtefactError(
                    file, "not a samples file (no models, no schema_version)",
                    "the samples file make dataset writes beside its shard",
                )  # fmt: skip
            attrs = attrs or {k: v for k, v in handle.attrs.items()}
            if score not in handle or "step" not in handle[score]:
                continue
            arrays = {name: handle[score][name][()] for name in SAMPLE_ARRAYS}
            models = {
                name: handle[f"models/{name}"].asstr()[()] for name in ("key", "category", "split")
            }
        _check_samples(file, score, arrays, len(models["key"]))
        for name, values in arrays.items():
            if name != "model":
                parts.setdefault(name, []).append(values)
        for name, column in models.items():
            parts.setdefault(name, []).append(np.asarray(column, dtype=str)[arrays["model"]])
    if not parts:
        raise DatasetError(f"{path}: no {score} samples in {len(files)} samples file(s)")
    return SampleSet(**{k: np.concatenate(v) for k, v in parts.items()}, attrs=attrs)
