"""Writing a dataset and an evaluation's selected views in PC-NBV's file layout.

PC-NBV (Zeng et al. 2020) keeps one PCD file per view (``pcd/<model>/<view>.pcd``), the
viewspace as a text file of camera positions, the start view of each experiment
(``test_init_<i>.txt``, one line per model of the model list) and the views a method selected
(``<method>/<i>/<model>_selected_views.txt``, one view index a line). Its scripts score a
reconstruction by the fraction of ground-truth points whose nearest merged-cloud point lies at
squared distance below 5e-5. The export writes the same files, so those scripts (or ten lines of
numpy and scipy) recompute our coverage and AUC from files alone::

    <out>/manifest.json                          what was exported, eps, our AUC of every episode
    <out>/README.md                              this layout, for whoever opens the folder
    <out>/<dataset>/models.txt                   model keys, one a line (PC-NBV's test.txt)
    <out>/<dataset>/gt/<model>.pcd               (n_gt, 3) ground truth
    <out>/<dataset>/<vs>/viewspace.txt           (V, 3) camera positions, one a line
    <out>/<dataset>/<vs>/pcd/<model>/<v>.pcd     view v's stored points (world frame)
    <out>/<dataset>/<vs>/coverage/<model>.npy    (V, ceil(n_gt / 8)) uint8 packed coverage bits
    <out>/<dataset>/<vs>/start/test_init_<i>.txt start view of experiment i, per model   (eval)
    <out>/<dataset>/<vs>/results/<method>/<i>/<model>_selected_views.txt  views in order (eval)

``<dataset>`` is the evaluation's dataset name (``unseen``, ``test``, ``meshes``; ``dataset``
for a dataset exported alone), ``<vs>`` the viewspace, ``<i>`` the experiment: the index of the
episode's start view in the run's sorted start views (PC-NBV numbers its experiments). A
stochastic method's repeat ``k > 0`` goes to ``<method>_repeat<k>``. Disturbed episodes (the
evaluation's checks) are not exported.

Frames and units: the dataset's normalised object frame (the object within radius 0.5), float32
points. PCD files are Open3D's (binary float32 by default, ASCII with 10 significant digits;
both give back the stored float32 values exactly). A view with no points is a header-only PCD
(``POINTS 0``), which Open3D reads as an empty cloud.

Coverage: the dataset's coverage bits come from the full-resolution views. When the dataset kept
every point (``points_per_view`` 0) the PCDs are those views and the coverage recomputed from
them equals ours. When the views were subsampled, the PCDs hold the subsample: coverage from
them is at most ours, and ``coverage/<model>.npy`` holds the bits ours came from
(``manifest.json``: ``coverage_from_pcd_is_exact``).

Every file is written to a temporary name and renamed; ``manifest.json`` is written last, so
an export without it was interrupted.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from nbv.dataset.reader import Dataset
from nbv.utils.atomic import atomic_path, fsync_replace, write_text

log = logging.getLogger(__name__)

FORMAT = "nbv -> PC-NBV export"
FORMAT_VERSION = 1
MANIFEST = "manifest.json"
#: The dataset name of a dataset exported without an evaluation.
DATASET_ONLY = "dataset"


class ExportError(ValueError):
    """A source or destination that cannot be exported to; the message names the file."""


def check_destination(out: Path) -> None:
    """Refuse an export folder that already holds an export: files of two exports must not mix.

    Raises:
        ExportError: ``out/manifest.json`` exists.
    """
    if (Path(out) / MANIFEST).exists():
        raise ExportError(
            f"out_dir={str(out)!r}: holds an earlier export ({MANIFEST}); give another out_dir "
            "or remove that one"
        )


@dataclass(frozen=True)
class Selection:
    """One evaluation episode to export.

    Attributes:
        dataset, viewspace, key: where it ran.
        method: the method name; repeat: the seed index of a stochastic method (0 otherwise).
        start: the start view; views: the captured views in order (start first).
        coverage: our coverage after each view; auc: our AUC of that curve.
    """

    dataset: str
    viewspace: str
    key: str
    method: str
    repeat: int
    start: int
    views: list[int]
    coverage: list[float]
    auc: float


@dataclass(frozen=True)
class Source:
    """One dataset to export: its name in the export, its folder, the models, the viewspaces."""

    name: str
    dataset: Dataset
    keys: list[str]
    viewspaces: list[str]


# Where each file goes: the layout of the module docstring, spelled once.
def models_path(out: Path, dataset: str) -> Path:
    return out / dataset / "models.txt"


def gt_path(out: Path, dataset: str, key: str) -> Path:
    return out / dataset / "gt" / f"{key}.pcd"


def viewspace_path(out: Path, dataset: str, viewspace: str) -> Path:
    return out / dataset / viewspace / "viewspace.txt"


def view_path(out: Path, dataset: str, viewspace: str, key: str, view: int) -> Path:
    return out / dataset / viewspace / "pcd" / key / f"{view}.pcd"


def coverage_path(out: Path, dataset: str, viewspace: str, key: str) -> Path:
    return out / dataset / viewspace / "coverage" / f"{key}.npy"


def start_path(out: Path, dataset: str, viewspace: str, experiment: int) -> Path:
    return out / dataset / viewspace / "start" / f"test_init_{experiment}.txt"


def method_folder(method: str, repeat: int) -> str:
    """``method`` for repeat 0, ``<method>_repeat<k>`` for the other seeds of a method."""
    return method if repeat == 0 else f"{method}_repeat{repeat}"


def selection_path(
    out: Path, dataset: str, viewspace: str, folder: str, experiment: int, key: str
) -> Path:
    folder_path = out / dataset / viewspace / "results" / folder / str(experiment)
    return folder_path / f"{key}_selected_views.txt"


_EMPTY_PCD = (
    "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
    "TYPE F F F\nCOUNT 1 1 1\nWIDTH 0\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 0\n"
    "DATA binary\n"
)


def write_pcd(path: Path, points: np.ndarray, ascii: bool = False) -> None:
    """Write an (N, 3) cloud as a PCD file with Open3D, whole or not at all.

    Open3D stores float32 (``SIZE 4``) in both modes; the float32 values read back exactly.
    N = 0 gives a header-only file (Open3D refuses to write an empty cloud).
    """
    import open3d as o3d

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Open3D picks the format from the extension, so the temporary name ends in .pcd too.
    tmp = path.with_name(path.stem + ".tmp.pcd")
    try:
        if len(points) == 0:
            tmp.write_text(_EMPTY_PCD)
        else:
            cloud = o3d.geometry.PointCloud()
            cloud.points = o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64))
            if not o3d.io.write_point_cloud(str(tmp), cloud, write_ascii=ascii):
                raise OSError(f"{path}: Open3D could not write the PCD file")
        fsync_replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def read_pcd(path: Path) -> np.ndarray:
    """The (N, 3) float32 points of a PCD file written by :func:`write_pcd`."""
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such PCD file")
    # A header-only file makes Open3D warn that it has no data; it is what an empty view is.
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        cloud = o3d.io.read_point_cloud(str(path), format="pcd")
    return np.asarray(cloud.points).astype(np.float32)


def _write_lines(path: Path, values: Iterable) -> None:
    write_text(path, "".join(f"{v}\n" for v in values))


def _write_npy(path: Path, array: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:  # a handle: np.save would append .npy to a name
            np.save(handle, array)


def _write_model(out: Path, source: Source, key: str, ascii: bool) -> dict[str, int]:
    """A model's ground truth and, per viewspace, its views and coverage bits; returns the
    viewspaces' points_per_view."""
    model = source.dataset.model(key, viewspaces=tuple(source.viewspaces))
    write_pcd(gt_path(out, source.name, key), model.gt_points, ascii)
    kept = {}
    for vs in source.viewspaces:
        view = model.views[vs]
        for v in range(len(view.poses)):
            write_pcd(view_path(out, source.name, vs, key, v), view.view_points(v), ascii)
        _write_npy(coverage_path(out, source.name, vs, key), view.coverage)
        kept[vs] = int(view.points_per_view)
    return kept


def _experiments(selections: Sequence[Selection]) -> dict[tuple[str, str], list[int]]:
    """(dataset, viewspace) -> the sorted start views; an experiment is an index into it."""
    starts: dict[tuple[str, str], set[int]] = {}
    for s in selections:
        starts.setdefault((s.dataset, s.viewspace), set()).add(s.start)
    return {k: sorted(v) for k, v in starts.items()}


def export(
    out: Path,
    sources: Sequence[Source],
    selections: Sequence[Selection] = (),
    *,
    ascii: bool = False,
    origin: dict | None = None,
    progress: bool = False,
) -> dict:
    """Write the export (layout: the module docstring) and return its manifest.

    Args:
        out: the export folder (created; files already there are replaced).
        sources: the datasets, each with the models and viewspaces to export.
        selections: the evaluation's episodes (none for a dataset exported alone); their
            dataset, viewspace and key must be among ``sources``.
        ascii: write ASCII PCD files instead of binary ones.
        origin: what was exported (recorded in the manifest as ``source``).
        progress: show a progress bar over the models.
    """
    from tqdm import tqdm

    out = Path(out)
    total = sum(len(s.keys) for s in sources)
    bar = tqdm(total=total, desc="export", unit="model", disable=not progress)
    datasets, points_per_view = {}, set()
    for source in sources:
        eps = float(source.dataset.attrs["eps"])
        _write_lines(models_path(out, source.name), source.keys)
        for vs in source.viewspaces:
            positions = source.dataset.viewspaces[vs]
            write_text(viewspace_path(out, source.name, vs), _rows(positions))
        kept: dict[str, int] = {}
        for key in source.keys:
            for vs, n in _write_model(out, source, key, ascii).items():
                kept[f"{key}/{vs}"] = n
            bar.update(1)
        points_per_view |= set(kept.values())
        datasets[source.name] = {
            "path": str(source.dataset.files[0].parent),
            "models": list(source.keys),
            "viewspaces": list(source.viewspaces),
            "n_gt": int(source.dataset.attrs["n_gt"]),
            "eps": eps,
            "points_per_view": sorted(set(kept.values())),
        }
    bar.close()

    experiments = _experiments(selections)
    keys = {s.name: s.keys for s in sources}
    for (dataset, vs), starts in experiments.items():
        by_model = {
            (s.key, s.start): s.start
            for s in selections
            if (s.dataset, s.viewspace) == (dataset, vs)
        }
        for i, start in enumerate(starts):
            # Every model of the list gets a line; one without this start view gets -1.
            lines = [by_model.get((k, start), -1) for k in keys[dataset]]
            _write_lines(start_path(out, dataset, vs, i), lines)
    episodes = []
    for s in selections:
        i = experiments[(s.dataset, s.viewspace)].index(s.start)
        folder = method_folder(s.method, s.repeat)
        path = selection_path(out, s.dataset, s.viewspace, folder, i, s.key)
        _write_lines(path, s.views)
        episodes.append(asdict(s) | {"experiment": i, "file": str(path.relative_to(out))})

    manifest = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "source": origin or {},
        "datasets": datasets,
        "experiments": {f"{d}/{vs}": starts for (d, vs), starts in experiments.items()},
        "coverage_from_pcd_is_exact": points_per_view <= {0},
        "auc": "(c_1 + ... + c_(n-1) + 0.5 c_n) / n, c_i the coverage after i views",
        "coverage": "fraction of gt points with a point of the merged views at distance < eps "
        "(PC-NBV: squared distance < 5e-5, eps = 0.00707)",
        "episodes": episodes,
    }
    write_text(out / "README.md", _readme())
    # Last: a folder with a manifest is a complete export.
    write_text(out / MANIFEST, json.dumps(manifest, indent=1, allow_nan=False))
    log.info("exported %d models and %d episodes to %s", total, len(episodes), out)
    return manifest


def _rows(array: np.ndarray) -> str:
    """One row a line, values with repr precision (float64 round trips exactly)."""
    return "".join(" ".join(repr(float(x)) for x in row) + "\n" for row in np.asarray(array))


def _readme() -> str:
    """The export's README.md: this module's docstring (its layout block is indented by four
    spaces, a code block in Markdown)."""
    return "# PC-NBV export\n\n" + (__doc__ or "")
