"""Reading a dataset: all shard files of a folder seen as one."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np

from nbv.dataset.records import ModelData
from nbv.dataset.schema import ROOT_ATTRS, SCHEMA_VERSION, read_model
from nbv.geometry.camera import Intrinsics
from nbv.utils.artefacts import ArtefactError, check_array, check_shape, reading

SHARD_GLOB = "shard-*-of-*.h5"
#: What a shard is, in a refusal.
SHARD = "dataset shard"


class DatasetError(ArtefactError):
    """A dataset that cannot be read; the message names the file."""

    def __init__(self, message: str):
        ValueError.__init__(self, message)


def check_model(model: ModelData, file: Path) -> None:
    """Refuse a model whose values break the shard's contract (``docs/dataset.md``): NaN or
    infinite ground truth, poses or points, offsets that do not rise from 0 to the number of
    points. Its arrays' shapes were checked when the shard was opened (:func:`_check_layout`).

    Raises:
        ArtefactError: naming ``file``, the model and the array.
    """
    where = f"models/{model.key}"
    check_array(model.gt_points, file, f"{where}/gt_points")
    for name, view in model.views.items():
        at = f"{where}/views/{name}"
        check_array(view.poses, file, f"{at}/poses")
        check_array(view.points, file, f"{at}/points")
        for offsets, points in ((view.offsets, view.points), (view.hull_offsets, view.hull_points)):
            if offsets[0] != 0 or np.any(np.diff(offsets) < 0) or offsets[-1] != len(points):
                raise ArtefactError(file, f"{at}: offsets do not index its {len(points)} points",
                                    "0, rising, up to the number of points")  # fmt: skip


#: A view group's arrays and their shapes; V = the views (the viewspace's, else the poses'),
#: N = any (docs/dataset.md).
VIEW_ARRAYS = {
    "poses": ("V", 4, 4),
    "points": ("N", 3),
    "offsets": ("V+1",),
    "coverage": ("V", "bits"),
    "hull_points": ("N", 3),
    "hull_offsets": ("V+1",),
}


def _check_layout(group: h5py.Group, file: Path, n_gt: int, viewspaces: dict) -> None:
    """Refuse a model group that lacks an array or holds one of the wrong shape (read from the
    file's metadata, not its data: cheap enough to do for every model when a dataset opens)."""
    where = group.name.lstrip("/")

    def shape_of(name: str) -> tuple[int, ...]:
        if name not in group or not isinstance(group[name], h5py.Dataset):
            raise ArtefactError(file, f"{where}/{name} is missing", "the arrays of docs/dataset.md")
        return group[name].shape

    check_shape(shape_of("gt_points"), file, f"{where}/gt_points", (n_gt, 3))
    if "views" not in group:
        raise ArtefactError(file, f"{where}/views is missing", "one group per viewspace")
    for name in group["views"]:
        poses = shape_of(f"views/{name}/poses")
        n = len(viewspaces[name]) if name in viewspaces else (poses[0] if poses else None)
        sizes = {"V": n, "V+1": None if n is None else n + 1, "N": None, "bits": (n_gt + 7) // 8}
        for array, shape in VIEW_ARRAYS.items():
            array_at = f"views/{name}/{array}"
            check_shape(shape_of(array_at), file, f"{where}/{array_at}",
                        tuple(sizes.get(d, d) for d in shape))  # fmt: skip


class Dataset:
    """Read access to every model of one or more shard files.

    Use :func:`open_dataset` (exported as ``nbv.dataset.open``). Models are read lazily, one at a
    time; the object holds only the index (key -> file) and the shared root attributes.

    Attributes:
        files: the shard files, sorted.
        attrs: root attributes shared by all shards (schema_version, eps, n_gt, camera, ...).
        viewspaces: name -> (V, 3) float64 camera positions.
        index: key -> (file, category, split), in file order.
        failures: (key, reason) of models that could not be produced.
    """

    def __init__(self, files: list[Path]):
        self.files = files
        self.index: dict[str, tuple[Path, str, str]] = {}
        self.failures: list[tuple[str, str]] = []
        self.attrs: dict = {}
        self.viewspaces: dict[str, np.ndarray] = {}
        for file in files:
            self._add(file)

    def _add(self, file: Path) -> None:
        with reading(file, SHARD), h5py.File(file, "r") as handle:
            missing = [name for name in ROOT_ATTRS if name not in handle.attrs]
            if missing:
                raise DatasetError(f"{file}: not a dataset shard, root attributes {missing} absent")
            attrs = {name: _plain(value) for name, value in handle.attrs.items()}
            if attrs["schema_version"] != SCHEMA_VERSION:
                raise DatasetError(
                    f"{file}: schema_version {attrs['schema_version']!r}; this code reads "
                    f"version {SCHEMA_VERSION} (docs/dataset.md); remake it with make dataset"
                )
            if not self.attrs:
                self.attrs = attrs
                self.viewspaces = {
                    k: check_array(v[()], file, f"viewspaces/{k}", (None, 3))
                    for k, v in handle["viewspaces"].items()
                }
            else:
                differ = [k for k in ROOT_ATTRS if attrs[k] != self.attrs[k]]
                if differ:
                    raise DatasetError(
                        f"{file}: settings {differ} differ from {self.files[0]}; shards of one "
                        "dataset must be generated with the same settings"
                    )
            for key, group in handle.get("models", {}).items():
                _check_layout(group, file, int(attrs["n_gt"]), self.viewspaces)
                if key in self.index:
                    raise DatasetError(f"{file}: model {key!r} also in {self.index[key][0]}")
                self.index[key] = (file, str(group.attrs["category"]), str(group.attrs["split"]))
            if "failures" in handle:
                self.failures += [(_text(k), _text(r)) for k, r in handle["failures"][()]]

    def __len__(self) -> int:
        return len(self.index)

    def __iter__(self) -> Iterator[str]:
        return iter(self.index)

    def __contains__(self, key: object) -> bool:
        return key in self.index

    def __getitem__(self, key: str) -> ModelData:
        return self.model(key)

    def model(self, key: str, viewspaces: tuple[str, ...] | None = None) -> ModelData:
        """Read one model (all viewspaces unless named)."""
        if key not in self.index:
            raise KeyError(f"model {key!r} is not in this dataset ({len(self)} models)")
        return self._read(key, viewspaces, depth=True)

    def _read(self, key: str, viewspaces: tuple[str, ...] | None, depth: bool) -> ModelData:
        """One model read and its values checked (:func:`check_model`)."""
        file = self.index[key][0]
        with reading(file, SHARD), h5py.File(file, "r") as handle:
            model = read_model(handle[f"models/{key}"], viewspaces, depth=depth)
        check_model(model, file)
        return model

    def verify(self, keys: list[str] | None = None) -> None:
        """Read and check the models (all unless named) as :meth:`model` does, leaving out the
        full-resolution depth: a command calls it before it writes anything, so that a bad
        model refuses the run instead of stopping it half-way.

        Raises:
            ArtefactError: the first bad model, naming its file and array.
        """
        for key in self.keys() if keys is None else keys:
            self._read(key, None, depth=False)

    def keys(self, split: str | None = None, category: str | None = None) -> list[str]:
        """Model keys, optionally only of one split and/or category."""
        return [
            k
            for k, (_, cat, spl) in self.index.items()
            if (split is None or spl == split) and (category is None or cat == category)
        ]

    @property
    def categories(self) -> list[str]:
        """Categories present, in order of first appearance."""
        return list(dict.fromkeys(cat for _, cat, _ in self.index.values()))

    @property
    def intrinsics(self) -> Intrinsics:
        """The camera the views were rendered with."""
        a = self.attrs
        return Intrinsics(int(a["width"]), int(a["height"]), a["fx"], a["fy"], a["cx"], a["cy"])


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _plain(value):
    """HDF5 attribute -> plain Python value (comparable with ==)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return _text(value) if isinstance(value, bytes) else value


def shard_files(path: str | Path) -> list[Path]:
    """The shard files of a dataset folder (or the one file given)."""
    path = Path(path)
    if path.is_file():
        return [path]
    if path.is_dir():
        files = sorted(path.glob(SHARD_GLOB))
        if not files:
            raise DatasetError(f"{path}: no shard files ({SHARD_GLOB}); run `make dataset` first")
        return files
    raise DatasetError(f"{path}: no such dataset file or folder; run `make dataset` first")


def check_eps(dataset: Dataset, eps: float, setting: str = "protocol.eps") -> None:
    """Refuse a dataset whose coverage bits were computed with another ``eps``.

    The bits fix the coverage criterion (squared distance ``< eps**2``); scoring them under a
    different ``eps`` would silently mix two criteria. The comparison is exact: the stored
    value is the float64 the bits were computed with.

    Args:
        dataset: the opened dataset (its root attribute ``eps``).
        eps: the eps the caller scores with (world units).
        setting: the name of the caller's setting, for the message.

    Raises:
        DatasetError: one line naming the files, both values and ``setting``.
    """
    stored = float(dataset.attrs["eps"])
    if stored != float(eps):
        where = dataset.files[0].parent if len(dataset.files) > 1 else dataset.files[0]
        raise DatasetError(
            f"{where}: its coverage bits were computed with eps={stored!r} but "
            f"{setting}={float(eps)!r}; regenerate the dataset (make dataset) or set "
            f"{setting}={stored!r}"
        )


def open_dataset(
    path: str | Path, eps: float | None = None, eps_setting: str = "protocol.eps"
) -> Dataset:
    """Open a dataset: one shard file, or a folder whose shards are read as one dataset.

    Args:
        path: a shard file or a dataset folder.
        eps: when given, the dataset must have been made with exactly this eps
            (:func:`check_eps`); None skips the check.
        eps_setting: the caller's name of that setting, for the message.
    """
    dataset = Dataset(shard_files(path))
    if eps is not None:
        check_eps(dataset, eps, eps_setting)
    return dataset
