"""What an evaluation runs on: the datasets opened (and ``mesh_dir`` prepared) and checked
against the viewspaces and start views (:func:`open_datasets`, :class:`DatasetInfo`), the models
that chose a network's checkpoint left out (:func:`exclude_selection`), the networks loaded
(:func:`load_networks`, :func:`with_shipped_weights`) and the methods' context on a dataset
(:func:`dataset_context`). :mod:`nbv.eval.evaluate` runs the episodes on them.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import nbv.dataset
from nbv.assets.categories import TRAIN_CATEGORIES, UNSEEN_CATEGORIES
from nbv.assets.mesh_sources import MESH_SOURCES, prepared_datasets
from nbv.dataset.reader import Dataset
from nbv.eval.config import EvalSettings
from nbv.eval.prepare import prepare_meshes, rendered_viewspaces, stored_name
from nbv.policies.method import MethodContext
from nbv.policies.network import NetworkPolicy
from nbv.policies.registry import METHODS, NETWORK_INPUTS, networks_of
from nbv.scan.shipped import ShippedCompletion, resolve_weights

log = logging.getLogger(__name__)


class EvalDataError(ValueError):
    """A dataset the evaluation cannot use; the message names the folder and the setting."""


@dataclass
class DatasetInfo:
    """One evaluated dataset.

    Attributes:
        name: ``unseen``, ``test`` or ``meshes``.
        path: its folder.
        keys: the evaluated models.
        failures: ``(key, reason)`` of models the dataset could not produce.
        flat: models whose ground truth has no hull volume (their VIG is undefined: NaN).
        qhull_failures: ``(key, message)`` of models whose ground truth Qhull failed on (VIG
            undefined, NaN; told apart from a flat ground truth).
        excluded: ``(key, reason)`` of models left out because their episodes chose a network
            checkpoint (scoring them would report on the selection data).
        sizes: viewspace -> its number of views.
        rendered: the dataset of the viewspaces ``path`` lacks, rendered by the evaluation
            (:func:`nbv.eval.prepare.rendered_viewspaces`); None when it lacked none.
    """

    name: str
    path: Path
    keys: list[str]
    failures: list[tuple[str, str]] = field(default_factory=list)
    flat: list[str] = field(default_factory=list)
    qhull_failures: list[tuple[str, str]] = field(default_factory=list)
    excluded: list[tuple[str, str]] = field(default_factory=list)
    sizes: dict[str, int] = field(default_factory=dict)
    rendered: Path | None = None


def _spread(keys: list[str], categories: list[str]) -> list[str]:
    """Keys reordered round-robin over their categories, so a ``limit`` takes every category."""
    by_cat: dict[str, list[str]] = {}
    for key, cat in zip(keys, categories, strict=True):
        by_cat.setdefault(cat, []).append(key)
    out = []
    for i in range(max((len(v) for v in by_cat.values()), default=0)):
        out += [v[i] for v in by_cat.values() if i < len(v)]
    return out


def open_datasets(settings: EvalSettings) -> list[tuple[DatasetInfo, Dataset]]:
    """Open (or prepare) each selected dataset and pick its models, in four steps a dataset:
    where it is (prepared from a mesh source's files when it is one), opened, its models, and
    its viewspaces (one it lacks is rendered for its models, once, cached:
    :func:`nbv.eval.prepare.rendered_viewspaces`).

    Raises:
        EvalDataError: a missing or empty dataset, a viewspace it lacks and cannot render, or
            a start view outside a viewspace.
    """
    out = []
    for name in settings.datasets:
        path, failures = _located(name, settings)
        try:
            ds = nbv.dataset.open(path, eps=settings.prepare.eps)
        except ValueError as err:
            raise EvalDataError(f"dataset={name} (data_dir={str(path)!r}): {err}") from None
        keys = _models(name, ds, path, settings.limit)
        sizes, rendered = _viewspaces(path, ds, keys, settings)
        failures += [f for f in ds.failures if f not in failures]
        out.append((DatasetInfo(name, path, keys, failures, sizes=sizes, rendered=rendered), ds))
    return out


def _located(name: str, settings: EvalSettings) -> tuple[Path, list[tuple[str, str]]]:
    """Where dataset ``name`` is: a prepared mesh source's cache (made when missing; with the
    meshes it could not make), else ``data_dir``."""
    prepared = prepared_datasets()
    if name not in prepared:
        return Path(settings.data_dir), []
    source = MESH_SOURCES[prepared[name]]
    root = source.installed() if source.installed else Path(settings.mesh_dir)
    return prepare_meshes(root, settings.prepare, settings.progress, source.name)


def _models(name: str, ds: Dataset, path: Path, limit: int | None) -> list[str]:
    """The models of dataset ``name`` an evaluation runs: a prepared dataset's all, the test
    split of the unseen or the training categories otherwise; spread over the categories and
    cut at ``limit``."""
    if name in prepared_datasets():
        keys, which = ds.keys(), "models"
    else:
        wanted = UNSEEN_CATEGORIES if name == "unseen" else TRAIN_CATEGORIES
        keys = [k for k in ds.keys(split="test") if ds.index[k][1] in wanted]
        which = (f"test-split models of the 8 {'unseen' if name == 'unseen' else 'training'} "
                 "categories")  # fmt: skip
    if not keys:
        raise EvalDataError(
            f"dataset={name}: {path} holds no {which} (categories there: {ds.categories})"
        )
    return _spread(keys, [ds.index[k][1] for k in keys])[:limit]


def _viewspaces(
    path: Path, ds: Dataset, keys: list[str], settings: EvalSettings
) -> tuple[dict[str, int], Path | None]:
    """Each selected viewspace's size, and the dataset of the viewspaces ``ds`` lacks,
    rendered for ``keys`` (None when it lacks none); every start view checked against them."""
    sizes = {vs: len(ds.viewspaces[vs]) for vs in settings.viewspaces if vs in ds.viewspaces}
    lacking = [vs for vs in settings.viewspaces if vs not in ds.viewspaces]
    rendered = None
    if lacking:
        text = ds.attrs.get("config")
        try:
            config = json.loads(text) if text else {}
            rendered = rendered_viewspaces(path, config, lacking, keys, Path(settings.prepare.dir),
                                           settings.progress)  # fmt: skip
            extra = nbv.dataset.open(rendered, eps=settings.prepare.eps)
        except ValueError as err:
            raise EvalDataError(f"viewspace={','.join(lacking)}: {err}") from None
        sizes.update({vs: len(extra.viewspaces[stored_name(vs)]) for vs in lacking})
    for vs, n in sizes.items():
        bad = [s for s in settings.start_views if s >= n]
        if bad:
            raise EvalDataError(f"start_views {bad} are outside viewspace {vs} (0..{n - 1})")
    return sizes, rendered


def _whose(method: str, network: str) -> str:
    """How a skip reason names the network of ``network`` for ``method``."""
    return "its network" if network == method else f"the network of {network} it runs"


def unusable(settings: EvalSettings, networks: dict, sizes: dict[str, int]) -> dict[str, str]:
    """``<method> on <viewspace>`` -> why: the selected methods that run a network with one
    output per view of a viewspace of another size (PCNBV's 33 outputs on ``hemisphere_30``)."""
    out = {}
    for method in settings.methods:
        for name in METHODS[method].networks:
            policy = networks.get(name)
            if not isinstance(policy, NetworkPolicy):
                continue  # not loaded, or viewspace-conditioned: it scores any direction
            outputs = policy.model.config.n_views
            for vs in settings.viewspaces:
                if sizes[vs] != outputs:
                    out[f"{method} on {vs}"] = (
                        f"{_whose(method, name)} has one output per view of a {outputs}-view "
                        f"viewspace; {vs} has {sizes[vs]} views"
                    )
    return out


def dataset_context(
    settings: EvalSettings, ds: Dataset, networks: dict[str, NetworkPolicy], scorer=None
) -> MethodContext:
    """What the methods of ``settings`` need on the dataset ``ds``: its camera and eps, the
    loaded networks, the run's planner settings, ``ig_learned``'s scorer (None without it) and
    the shipped completion network (loaded when a completion planner first runs)."""
    return MethodContext(networks, settings.setcover, ds.intrinsics, float(ds.attrs["eps"]),
                         settings.n_views, settings.infogain, scorer=scorer,
                         completion=ShippedCompletion())  # fmt: skip


def exclude_selection(info: DatasetInfo, ds: Dataset, networks: dict[str, NetworkPolicy]) -> None:
    """Leave out of ``info.keys`` the models whose episodes chose a network's checkpoint, for
    every method (the comparison stays paired), noting each in ``info.excluded``."""
    if info.name in prepared_datasets():
        return
    keep = []
    for key in info.keys:
        marks = (key, f"category:{ds.index[key][1]}")
        chose = [m for m, net in networks.items() if any(k in net.selected_on for k in marks)]
        if chose:
            info.excluded.append((key, f"chose the checkpoint of {', '.join(chose)}"))
        else:
            keep.append(key)
    if info.excluded:
        log.warning("dataset=%s: %d models left out: they chose a network's checkpoint",
                    info.name, len(info.excluded))  # fmt: skip
    info.keys = keep
    if not keep:
        raise EvalDataError(
            f"dataset={info.name}: every model chose a network checkpoint; nothing to score"
        )


def load_networks(
    settings: EvalSettings, n_views: int | None
) -> tuple[dict[str, NetworkPolicy], dict[str, str]]:
    """The checkpoints of the networks the selected methods run (:func:`networks_of`), as they
    are (no fallback to the shipped weights: :func:`with_shipped_weights`): (network method ->
    policy, selected method -> skip reason). Only a checkpoint that does not exist is skipped
    (a default path with no shipped weights behind it); a method led by another's network is
    skipped when that network is. A file that exists and cannot be used refuses the run.

    ``n_views``: the viewspace's size a PCNBV network must have; None: any (see
    :func:`unusable`)."""
    from nbv.models.checkpoints import CheckpointError

    networks, failed = {}, {}
    for method in networks_of(settings.methods):
        needed = NETWORK_INPUTS[method]
        path = settings.checkpoints[method]
        try:
            policy = METHODS[method].load(path, n_views, settings.precision)
        except CheckpointError as err:
            if Path(path).exists():  # a file that is there but unusable is never skipped
                raise EvalDataError(f"checkpoints.{method}: {err}") from None
            failed[method] = str(err)
            continue
        if policy.input != needed:
            raise EvalDataError(
                f"checkpoints.{method}: {path} holds a network on {policy.input}, not {needed}"
            )
        networks[method] = policy
    skipped = {}
    for method in settings.methods:
        for name in METHODS[method].networks:
            if name in failed:
                reason = failed[name]
                skipped[method] = reason if name == method else f"{_whose(method, name)}: {reason}"
    return networks, skipped


def with_shipped_weights(settings: EvalSettings) -> EvalSettings:
    """The settings with the checkpoint of each network the selected methods run as the
    registry resolves it
    (:func:`nbv.scan.shipped.resolve_weights`: the checkpoint when it exists, else the
    weights the package ships, logged). A missing checkpoint the package ships nothing for stays:
    :func:`load_networks` skips its method, naming the path."""
    found = {}
    needed = networks_of(settings.methods)
    for method, path in settings.checkpoints.items():
        if method not in needed:
            continue
        try:
            weights = resolve_weights(method, path)
        except ValueError:  # no checkpoint and nothing shipped: skipped when loaded
            continue
        if weights != Path(path):
            found[method] = str(weights)
    if not found:
        return settings
    return dataclasses.replace(settings, checkpoints={**settings.checkpoints, **found})


def open_inputs(settings: EvalSettings) -> tuple[list, dict, dict[str, str], dict[str, str]]:
    """What a run reads before its episodes: (the opened datasets (:func:`open_datasets`), the
    loaded networks, every method that cannot run -> why (:func:`load_networks` and
    :func:`unusable`), the unusable ones alone (method on viewspace -> why))."""
    opened = open_datasets(settings)
    networks, skipped = load_networks(settings, None)
    skip_on = unusable(settings, networks, {vs: n for i, _ in opened for vs, n in i.sizes.items()})
    return opened, networks, {**skipped, **skip_on}, skip_on
