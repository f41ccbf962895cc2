"""Writing a dataset and an evaluation's selected views in PC-NBV's file layout.

PC-NBV (Zeng et al. 2020) keeps one PCD file per view (``pcd/<model>/<view>.pcd``, world frame),
the ground truth of each model as ``<model_dir>/<class>/<model>/model.mat`` (key ``points``), the
start view of each experiment (``test_init_<i>.txt``, one line per model of the model list) and
the views a method selected (``<method>/<i>/<model>_selected_views.txt``, one view index a line).
Its scripts count a ground-truth point covered when the merged views of an episode hold a point at
squared distance below 5e-5, and take the AUC ``(c_1 + ... + c_9 + 0.5 c_10) / 10``. The export
writes those files, so its scripts (or twenty lines of numpy) recompute our coverage and AUC from
files alone::

    <out>/manifest.json                          what was exported, eps, how the views were had,
                                                 our coverage and AUC of every episode
    <out>/README.md                              this layout, for whoever opens the folder
    <out>/<dataset>/models.txt                   model keys, one a line (PC-NBV's test list)
    <out>/<dataset>/classes.txt                  the classes (categories), one a line
    <out>/<dataset>/gt/<class>/<model>/model.mat ground truth: "points", (n_gt, 3) float32;
                                                 <out>/<dataset>/gt is PC-NBV's model_dir
    <out>/<dataset>/<vs>/viewspace.txt           (V, 3) camera positions, one a line
    <out>/<dataset>/<vs>/pcd/<model>/<v>.pcd     view v at FULL resolution (world frame)
    <out>/<dataset>/<vs>/coverage/<model>.npy    (V, ceil(n_gt / 8)) uint8 packed coverage bits
    <out>/<dataset>/<vs>/start/test_init_<i>.txt start view of experiment i, one line per model
    <out>/<dataset>/<vs>/results/<method>/<i>/<model>_selected_views.txt  views in order (eval)

``<dataset>`` is the evaluation's dataset name (``unseen``, ``test``, ``meshes``; ``dataset``
for a dataset exported alone), ``<class>`` the model's category as the dataset names it,
``<vs>`` the viewspace, ``<i>`` the experiment: the index of the episode's start view in the run's
sorted start views (PC-NBV numbers its experiments); every line of ``test_init_<i>.txt`` is that
start view, and every model of ``models.txt`` has an episode from it for every exported method.
A stochastic method's repeat ``k > 0`` goes to ``<method>_repeat<k>``. Disturbed episodes (the
evaluation's checks) are not exported.

Views: the PCDs hold every point of each view, the clouds the dataset's coverage bits were
computed from (:mod:`nbv.export.views`: the stored points of a dataset that kept them all, else
the views ray cast again from the source mesh), each checked to cover exactly the ground-truth
points its bits say. A view with no point holds the single point (1, 1, 1), which covers nothing
(an empty cloud would count as full coverage in PC-NBV's nearest-neighbour kernel).

Frames, units, files: the dataset's normalised object frame (the object within radius 0.5). PCD
files (PCL's v0.7 format, fields x y z) are binary float32 (``ascii``: ASCII, each float32
written with the digits of its exact float64 value, which Open3D reads back exactly). The rare
view whose float32 copy would cover a different set of ground-truth points is written in float64
as ASCII with 17 significant digits (Open3D's reader reads those exactly; it cannot read binary
float64); ``manifest.json`` lists those views and the empty ones.

Coverage: ``coverage/<model>.npy`` holds the bits ours came from
(``np.unpackbits(bits, axis=1, count=n_gt)``); the coverage the PCDs give under the dataset's
eps equals them, view by view. ``manifest.json``'s ``pcnbv_criterion`` says whether that eps is
PC-NBV's (``eps * eps == 5e-5`` in float64); a dataset made with another eps scores a few
ground-truth points differently under PC-NBV's scripts.

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
from nbv.export.errors import ExportError
from nbv.export.views import FullViews
from nbv.utils.atomic import atomic_path, write_text

__all__ = ["ExportError", "Selection", "Source", "export", "read_pcd", "write_mat", "write_pcd"]

log = logging.getLogger(__name__)

FORMAT = "nbv -> PC-NBV export"
FORMAT_VERSION = 2
MANIFEST = "manifest.json"
#: The dataset name of a dataset exported without an evaluation.
DATASET_ONLY = "dataset"
#: PC-NBV's coverage test: squared distance below this.
PCNBV_SQUARED_EPS = 5e-5


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
    """One dataset to export: its name in the export, its folder, the models, the viewspaces,
    and how its full-resolution views are had (checked when the source is made)."""

    name: str
    dataset: Dataset
    keys: list[str]
    viewspaces: list[str]
    full: FullViews


# Where each file goes: the layout of the module docstring, spelled once.
def models_path(out: Path, dataset: str) -> Path:
    return out / dataset / "models.txt"


def classes_path(out: Path, dataset: str) -> Path:
    return out / dataset / "classes.txt"


def model_dir(out: Path, dataset: str) -> Path:
    """PC-NBV's ``model_dir``: the folder of ``<class>/<model>/model.mat``."""
    return out / dataset / "gt"


def gt_path(out: Path, dataset: str, category: str, key: str) -> Path:
    return model_dir(out, dataset) / category / key / "model.mat"


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


def _pcd_header(n: int, size: int, data: str) -> str:
    """PCL's v0.7 header of ``n`` points x y z of ``size`` bytes each (Open3D writes the same)."""
    return (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\n"
        f"SIZE {size} {size} {size}\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\n"
        f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n"
    )


def write_pcd(path: Path, points: np.ndarray, ascii: bool = False) -> None:
    """Write an (N, 3) cloud as a PCD file, whole or not at all; Open3D reads back its values.

    float32 points: binary (``SIZE 4``), or ASCII (``SIZE 4``) with the digits of their exact
    float64 value (Open3D parses ASCII into doubles). float64 points: ASCII with 17 significant
    digits (``SIZE 8``) whatever ``ascii`` says, since Open3D's reader cannot read binary
    float64. Other dtypes are refused.
    """
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{path}: points must be (N, 3), got {points.shape}")
    if points.dtype == np.float32 and not ascii:
        data = _pcd_header(len(points), 4, "binary").encode() + points.astype("<f4").tobytes()
    elif points.dtype in (np.float32, np.float64):
        # The shortest digits of the value as a float64: Open3D parses ASCII into doubles
        # (also for SIZE 4), so a float32's own shortest digits would come back another value.
        values = points.astype(np.float64).tolist()
        rows = "".join(" ".join(map(repr, row)) + "\n" for row in values)
        data = (_pcd_header(len(points), points.dtype.itemsize, "ascii") + rows).encode()
    else:
        raise ValueError(f"{path}: points must be float32 or float64, got {points.dtype}")
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def read_pcd(path: Path) -> np.ndarray:
    """The (N, 3) points of a PCD file, read by Open3D (float64: the values written, exactly)."""
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such PCD file")
    cloud = o3d.io.read_point_cloud(str(path), format="pcd")
    return np.asarray(cloud.points, dtype=np.float64)


def write_mat(path: Path, points: np.ndarray) -> None:
    """The ground truth as PC-NBV reads it: a MATLAB file whose ``points`` is (N, 3), as given."""
    from scipy.io import savemat

    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        savemat(handle, {"points": np.asarray(points)})


def _write_lines(path: Path, values: Iterable) -> None:
    write_text(path, "".join(f"{v}\n" for v in values))


def _write_npy(path: Path, array: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:  # a handle: np.save would append .npy to a name
            np.save(handle, array)


def _write_model(out: Path, source: Source, key: str, ascii: bool) -> dict[str, dict]:
    """A model's ground truth and, per viewspace, its full views and coverage bits; returns
    viewspace -> how its views were had (:class:`~nbv.export.views.ViewNotes` as a dict)."""
    # Re-casting a noisy dataset needs every viewspace of the model (the noise's order).
    wanted = None if source.full.noise else tuple(source.viewspaces)
    model = source.dataset.model(key, viewspaces=wanted)
    write_mat(gt_path(out, source.name, model.category, key), model.gt_points)
    notes = {}
    for vs in source.viewspaces:
        clouds, noted = source.full.views(model, vs)
        for v, cloud in enumerate(clouds):
            write_pcd(view_path(out, source.name, vs, key, v), cloud, ascii)
        _write_npy(coverage_path(out, source.name, vs, key), model.views[vs].coverage)
        notes[vs] = asdict(noted)
    return notes


def _experiments(selections: Sequence[Selection]) -> dict[tuple[str, str], list[int]]:
    """(dataset, viewspace) -> the sorted start views; an experiment is an index into it."""
    starts: dict[tuple[str, str], set[int]] = {}
    for s in selections:
        starts.setdefault((s.dataset, s.viewspace), set()).add(s.start)
    return {k: sorted(v) for k, v in starts.items()}


def check_complete(sources: Sequence[Source], selections: Sequence[Selection]) -> None:
    """Every exported method (and repeat) has an episode for every model of its dataset from
    every start view of its viewspace: PC-NBV's scripts read one line a model of each start
    file and that model's selected views.

    Raises:
        ExportError: the first (dataset, viewspace, method) that misses episodes, naming them.
    """
    keys = {s.name: s.keys for s in sources}
    experiments = _experiments(selections)
    have: dict[tuple[str, str, str], set[tuple[str, int]]] = {}
    for s in selections:
        folder = method_folder(s.method, s.repeat)
        have.setdefault((s.dataset, s.viewspace, folder), set()).add((s.key, s.start))
    for (dataset, vs, folder), got in have.items():
        missing = [(k, st) for st in experiments[(dataset, vs)] for k in keys[dataset]
                   if (k, st) not in got]  # fmt: skip
        if missing:
            shown = ", ".join(f"{k} from view {st}" for k, st in missing[:5])
            more = f" and {len(missing) - 5} more" if len(missing) > 5 else ""
            raise ExportError(
                f"{dataset}/{vs}/{folder}: no episode of {shown}{more}; PC-NBV's layout needs "
                "every model from every start view (choose methods= or viewspace= that have them)"
            )


def _write_source(out: Path, source: Source, ascii: bool, bar) -> dict:
    """One dataset's model and class lists, viewspaces and models; its manifest entry."""
    eps = float(source.dataset.attrs["eps"])
    if eps * eps != PCNBV_SQUARED_EPS:
        log.warning("%s: eps=%r, not PC-NBV's sqrt(5e-5): its scripts will score a few "
                    "ground-truth points differently", source.name, eps)  # fmt: skip
    classes = {k: source.dataset.index[k][1] for k in source.keys}
    _write_lines(models_path(out, source.name), source.keys)
    _write_lines(classes_path(out, source.name), dict.fromkeys(classes.values()))
    for vs in source.viewspaces:
        write_text(viewspace_path(out, source.name, vs), _rows(source.dataset.viewspaces[vs]))
    views = {}
    for key in source.keys:
        views[key] = _write_model(out, source, key, ascii)
        bar.update(1)
    return {
        "path": str(source.dataset.files[0].parent),
        "models": list(source.keys),
        "classes": classes,
        "viewspaces": list(source.viewspaces),
        "n_gt": int(source.dataset.attrs["n_gt"]),
        "eps": eps,
        "pcnbv_criterion": eps * eps == PCNBV_SQUARED_EPS,
        "points_per_view": source.full.config.get("points_per_view"),
        "views": views,
    }


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
            dataset, viewspace and key must be among ``sources``, every model from every start.
        ascii: write ASCII PCD files instead of binary ones.
        origin: what was exported (recorded in the manifest as ``source``).
        progress: show a progress bar over the models.

    Raises:
        ExportError: before anything is written, an incomplete set of episodes
            (:func:`check_complete`); while writing, a view whose full cloud does not reproduce
            its coverage bits (:class:`~nbv.export.views.FullViews`; the folder then has no
            ``manifest.json``).
    """
    from tqdm import tqdm

    check_complete(sources, selections)
    out = Path(out)
    total = sum(len(s.keys) for s in sources)
    bar = tqdm(total=total, desc="export", unit="model", disable=not progress)
    datasets = {source.name: _write_source(out, source, ascii, bar) for source in sources}
    bar.close()

    experiments = _experiments(selections)
    for (dataset, vs), starts in experiments.items():
        n_models = len(datasets[dataset]["models"])
        for i, start in enumerate(starts):
            # Experiment i starts every model at this view (check_complete: all have it).
            _write_lines(start_path(out, dataset, vs, i), [start] * n_models)
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
        "coverage_from_pcd_is_exact": True,
        "auc": "(c_1 + ... + c_(n-1) + 0.5 c_n) / n, c_i the coverage after i views",
        "coverage": "fraction of gt points with a point of the merged views at squared distance "
        "< eps * eps (float64); PC-NBV: squared distance < 5e-5, eps = sqrt(5e-5)",
        "empty_view": "a view with no point holds the single point (1, 1, 1)",
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
