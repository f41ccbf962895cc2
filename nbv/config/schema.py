"""The schemas of the shared config groups, and a config checked against its schema.

A schema is a dataclass registered in hydra's ConfigStore; a primary config names it first in
its defaults list (``defaults: [dataset_schema, ..., _self_]``), so that hydra refuses an unknown
key or a value of the wrong type while it composes, before any folder is made. The schemas hold
no values (every field is ``MISSING``): the values live in ``conf/``, written once.
"""

from __future__ import annotations

import dataclasses
import typing
from dataclasses import dataclass
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, ListConfig, OmegaConf
from omegaconf.errors import (
    ConfigAttributeError,
    ConfigKeyError,
    MissingMandatoryValue,
    OmegaConfBaseException,
    ValidationError,
)

# Defined with the fields that raise it (the library's settings raise it too); the entry points
# import it from here.
from nbv.utils.fields import ConfigError, renamed_line


def names(value: Any, key: str) -> tuple[str, ...]:
    """A setting that takes null, one name or a list of names, as a tuple of names."""
    if value is None:
        return ()
    if isinstance(value, str):
        return (value,)
    if isinstance(value, list | tuple) and all(isinstance(v, str) for v in value):
        return tuple(value)
    raise ConfigError(f"{key}={value!r}: must be null, a name or a list of names")


@dataclass
class CameraConfig:
    """``conf/camera/``: a pinhole camera, principal point at the image centre, fx = fy."""

    width: int = MISSING
    height: int = MISSING
    focal: float = MISSING


@dataclass
class ProtocolConfig:
    """``conf/protocol/``: how episodes run and how views are scored.

    Attributes:
        start_views: the episodes' first views (indices into the viewspace).
        n_views: views per episode, the start view included.
        eps: coverage distance (world units; objects fit in a sphere of radius 0.5).
        n_gt: ground-truth points sampled uniformly on the normalised mesh.
        points_per_view: points kept of each view (a seeded random subset); 0 keeps all.
        viewspaces: the viewspaces the dataset renders and the evaluation runs on.
    """

    start_views: list[int] = MISSING
    n_views: int = MISSING
    eps: float = MISSING
    n_gt: int = MISSING
    points_per_view: int = MISSING
    viewspaces: list[str] = MISSING


@dataclass
class PathsConfig:
    """``conf/paths/``: the folders and files the entry points share.

    Attributes:
        dataset: the dataset folder ``make dataset`` writes and training, evaluation and the
            bench read.
        outputs: root of the run folders (``<outputs>/<entry point>/...``).
        multirun: root of hydra's multirun folders.
        checkpoints: network method name -> the ``best.pt`` evaluation and the bench use.
    """

    dataset: str = MISSING
    outputs: str = MISSING
    multirun: str = MISSING
    checkpoints: dict[str, str] = MISSING


def register(name: str, node: type) -> None:
    """Store the schema ``node`` in hydra's ConfigStore as ``name`` (for a defaults list)."""
    ConfigStore.instance().store(name=name, node=node)


def _listed(kind: Any) -> Any:
    """``tuple[X, ...]`` as ``list[X]`` (what OmegaConf holds); other types unchanged."""
    if typing.get_origin(kind) is tuple:
        return list[typing.get_args(kind)[0]]
    return kind


def schema_of(
    settings: type, name: str, optional: bool = False, exclude: tuple[str, ...] = ()
) -> type:
    """A structured-config dataclass with the field names and types of a settings dataclass.

    OmegaConf turns a frozen dataclass into a read-only node, so frozen settings cannot be a
    schema themselves; this copies their fields instead (tuples become lists), so that the
    settings class stays the one place that names them.

    Args:
        settings: the settings dataclass.
        name: the schema's class name.
        optional: every field may be null (meaning: the settings' default) and is null unless
            given; otherwise every field must be given.
        exclude: fields left out.
    """
    hints = typing.get_type_hints(settings)
    fields = []
    for f in dataclasses.fields(settings):
        if f.name in exclude:
            continue
        kind = _listed(hints[f.name])
        if optional:
            fields.append((f.name, kind | None, dataclasses.field(default=None)))
        else:
            fields.append((f.name, kind, dataclasses.field(default=MISSING)))
    return dataclasses.make_dataclass(name, fields)


def _plain(cfg: Any) -> dict:
    """The config without its ``hydra`` node, interpolations resolved, as plain containers.

    Resolved in the composed config itself, so that ``${now:...}`` gives the value hydra's run
    folder was named with (hydra caches it there)."""
    if not isinstance(cfg, DictConfig):
        return {k: v for k, v in dict(cfg).items() if k != "hydra"}
    out = {}
    for key in cfg:
        if key == "hydra":
            continue
        value = cfg[key]
        if isinstance(value, DictConfig | ListConfig):
            value = OmegaConf.to_container(value, resolve=True)
        out[key] = value
    return out


def validated(schema: type, cfg: Any) -> dict:
    """``cfg`` checked against ``schema``: a plain dict, every interpolation resolved.

    Args:
        schema: the structured-config dataclass.
        cfg: a composed hydra config or a plain dict (its ``hydra`` node is ignored).

    Raises:
        ConfigError: an unknown key (also one added with ``+key=...``), a value of the wrong
            type, a missing value; the message names the key path.
    """
    try:
        merged = OmegaConf.merge(OmegaConf.structured(schema), _plain(cfg))
        return OmegaConf.to_container(merged, resolve=True, throw_on_missing=True)
    except OmegaConfBaseException as err:
        raise ConfigError(describe(err)) from None


#: OmegaConf's words for a value of the wrong type -> what the key needs.
_EXPECTED = (
    ("to Integer", "an integer"),
    ("to Float", "a number"),
    ("valid bool", "true or false"),
    ("to string", "a string"),
    ("is not a ListConfig", "a list"),
    ("to Dict", "a mapping"),
    ("is not a subclass of", "a mapping"),
)


def _field_names(kind: Any) -> list[str]:
    return [f.name for f in dataclasses.fields(kind)] if dataclasses.is_dataclass(kind) else []


def _omegaconf_line(err: OmegaConfBaseException) -> str:
    key = err.full_key or err.key
    first = str(err.msg or err).splitlines()[0]
    if isinstance(err, ConfigKeyError | ConfigAttributeError) and " not in " in first:
        renamed = renamed_line(key)
        if renamed:
            return renamed
        allowed = _field_names(getattr(err, "object_type", None))
        return f"{key}: unknown key" + (f"; allowed: {', '.join(allowed)}" if allowed else "")
    if isinstance(err, MissingMandatoryValue):
        return f"{key}: no value; the config must give one"
    if isinstance(err, ValidationError):
        for words, wanted in _EXPECTED:
            if words in first:
                return f"{key}={err.value!r}: must be {wanted}"
    return f"{key}: {first}"


def _squash(text: str) -> str:
    """A multi-line hydra message on one line; the lines after one ending in ':' as a list."""
    text = text.split("\nConfig search path")[0]
    parts: list[str] = []
    listing = False
    for line in (line.strip() for line in text.splitlines()):
        if not line:
            continue
        if listing:
            parts[-1] += (" " if parts[-1].endswith(":") else ", ") + line
        else:
            parts.append(line)
        listing = listing or line.endswith(":")
    return "; ".join(part.rstrip(".") for part in parts)


def describe(err: BaseException) -> str:
    """One line for a config error of hydra or OmegaConf: the key path and what is wrong."""
    cause = err if isinstance(err, OmegaConfBaseException) else err.__cause__
    if isinstance(cause, OmegaConfBaseException) and (cause.full_key or cause.key):
        return _omegaconf_line(cause)
    override = getattr(err, "override", None)  # hydra's OverrideParseException
    return (f"{override}: " if isinstance(override, str) else "") + _squash(str(err))


def check_views(key: str, views: Any, viewspace: str, n: int) -> None:
    """Refuse view indices outside a viewspace of ``n`` views, saying how many it has.

    Raises:
        ConfigError: e.g. ``start_views=[40]: the viewspace 'original' has 33 views (indices
            0..32)``.
    """
    bad = [int(v) for v in views if not 0 <= v < n]
    if bad:
        raise ConfigError(
            f"{key}={bad}: the viewspace {viewspace!r} has {n} views (indices 0..{n - 1})"
        )
