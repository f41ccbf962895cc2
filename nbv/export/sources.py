"""What an export reads: a finished evaluation run or a dataset, checked before any writing.

Both give the :class:`~nbv.export.pcnbv_format.Source` datasets (models and viewspaces) and,
for a run, the :class:`~nbv.export.pcnbv_format.Selection` of each undisturbed episode. Each
dataset must give its full-resolution views (:class:`~nbv.export.views.FullViews`). Every
refusal is one :class:`ExportError` naming the file and what is wrong with it.
"""

from __future__ import annotations

import json
from pathlib import Path

import nbv.dataset
from nbv.export.errors import ExportError
from nbv.export.pcnbv_format import DATASET_ONLY, Selection, Source
from nbv.export.views import FullViews
from nbv.utils.artefacts import ArtefactError, reading

__all__ = ["ExportError", "from_dataset", "from_eval_run"]

#: The keys of an evaluation's results.json that the export reads.
RESULT_KEYS = ("datasets", "episodes")


def _open(path: Path, where: str) -> nbv.dataset.Dataset:
    try:
        return nbv.dataset.open(path)
    except ValueError as err:
        raise ExportError(f"{where}: {err}") from None


def _chosen(kind: str, wanted: tuple[str, ...], present: list[str], where: str) -> list[str]:
    """``wanted`` (all of ``present`` when empty), each of them present."""
    missing = [n for n in wanted if n not in present]
    if missing:
        raise ExportError(f"{kind}: {missing} not in {where}; there: {present}")
    return list(wanted) if wanted else present


def from_dataset(
    path: Path, viewspaces: tuple[str, ...] = (), limit: int | None = None
) -> list[Source]:
    """A dataset folder or shard file: its models (the first ``limit``) and viewspaces."""
    ds = _open(Path(path), f"data_dir={str(path)!r}")
    keys = ds.keys()[:limit]
    if not keys:
        raise ExportError(f"data_dir={str(path)!r}: the dataset holds no models")
    chosen = _chosen("viewspace", viewspaces, list(ds.viewspaces), str(path))
    return [Source(DATASET_ONLY, ds, keys, chosen, FullViews(ds))]


def _results(run: Path) -> dict:
    path = Path(run) / "results.json"
    if not Path(run).is_dir():
        raise ExportError(f"eval_run={str(run)!r}: no such folder")
    if not path.is_file():
        raise ExportError(
            f"{path}: no such file; export needs a finished `python -m nbv.eval` run "
            "(results.json is written at its end)"
        )
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ExportError(f"{path}: not JSON ({err})") from None
    missing = [k for k in RESULT_KEYS if not isinstance(data, dict) or k not in data]
    if missing:
        raise ExportError(f"{path}: no {missing}; not the results.json of python -m nbv.eval")
    return data


def _selection(dataset: str, episode: dict) -> Selection:
    """An episode of results.json as a :class:`Selection`."""
    return Selection(
        dataset=dataset,
        viewspace=episode["viewspace"],
        key=episode["key"],
        method=episode["method"],
        repeat=int(episode.get("repeat", 0)),
        start=int(episode["start"]),
        views=[int(v) for v in episode["views"]],
        coverage=[float(c) for c in episode["coverage"]],
        auc=float(episode["auc"]),
    )


def from_eval_run(
    run: Path,
    viewspaces: tuple[str, ...] = (),
    methods: tuple[str, ...] = (),
    limit: int | None = None,
) -> tuple[list[Source], list[Selection]]:
    """A finished evaluation: its datasets and the undisturbed episodes (check null) of the
    chosen viewspaces and methods, for the first ``limit`` models of each dataset."""
    data = _results(run)
    where = str(Path(run) / "results.json")
    # An episode or dataset entry without its keys, or with values of the wrong type, is a
    # results.json that cannot be used: one refusal naming it.
    try:
        with reading(where, "results.json of python -m nbv.eval"):
            return _gather(data, where, viewspaces, methods, limit)
    except ArtefactError as err:
        raise ExportError(str(err)) from None


def _gather(
    data: dict, where: str, viewspaces: tuple[str, ...], methods: tuple[str, ...], limit: int | None
) -> tuple[list[Source], list[Selection]]:
    episodes = [e for e in data["episodes"] if e.get("check") is None]
    run_methods = list(dict.fromkeys(e["method"] for e in episodes))
    run_viewspaces = list(dict.fromkeys(e["viewspace"] for e in episodes))
    methods_ = _chosen("methods", methods, run_methods, where)
    viewspaces_ = _chosen("viewspace", viewspaces, run_viewspaces, where)
    sources, selections = [], []
    for info in data["datasets"]:
        name, path = info["name"], Path(info["path"])
        ds = _open(path, f"{where}: dataset {name!r}")
        mine = [e for e in episodes if e["dataset"] == name
                and e["method"] in methods_ and e["viewspace"] in viewspaces_]  # fmt: skip
        with_episodes = {e["key"] for e in mine}
        keys = [k for k in info["keys"] if k in with_episodes][:limit]
        absent = [k for k in keys if k not in ds]
        if absent:
            raise ExportError(f"{where}: models {absent} are not in the dataset at {path}")
        if not keys:
            continue
        used = [vs for vs in viewspaces_ if any(e["viewspace"] == vs for e in mine)]
        sources.append(Source(name, ds, keys, used, FullViews(ds)))
        selections += [_selection(name, e) for e in mine if e["key"] in keys]
    if not selections:
        raise ExportError(f"{where}: no undisturbed episodes of {methods_} on {viewspaces_}")
    return sources, selections
