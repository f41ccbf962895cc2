"""One declaration per setting: the frozen settings dataclass is the only place a key is written.

A settings dataclass, nested like its YAML file, names each key, its type, its default and (with
:func:`setting`) its allowed range. From it come

- :func:`schema`: the hydra structured config (a plain dataclass with the same keys, types that
  OmegaConf holds, and the same defaults), registered for the YAML's defaults list, so that hydra
  refuses an unknown key or a value of the wrong type while it composes;
- :func:`build`: the settings object made from a composed config, every range checked, the
  message of a bad value naming its key path (``setcover.n_samp=0: must be an integer >= 1``);
- :func:`check_ranges`: the same range checks, for ``__post_init__`` (a settings object made in
  code is checked as one made from a config).

A YAML file therefore only overrides a default (and says why), or interpolates a shared group
(``${protocol.eps}``). Checks that span several fields stay in the class's ``__post_init__``.

Field metadata understood here (set it with :func:`setting`):

- ``check`` / ``allowed``: a predicate on the value, and the words for what it must be;
- ``key``: the YAML key when it differs from the field's name;
- ``config`` / ``convert``: the type the YAML holds when the field's own type is not one
  OmegaConf can hold (e.g. a camera ``{width, height, focal}`` for an ``Intrinsics``), and the
  function that turns the YAML value into the field's value;
- ``config_default``: that YAML value's default, when the field's default cannot be written back.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omegaconf import MISSING

from nbv.config.schema import register, validated
from nbv.utils.fields import check_ranges, fields_of, key_of, setting
from nbv.utils.settings_values import construct, plain
from nbv.utils.settings_values import is_settings as _is_settings
from nbv.utils.settings_values import union_args as _union_args

__all__ = [
    "Entry",
    "as_config",
    "build",
    "check_ranges",
    "key_of",
    "plain",
    "schema",
    "setting",
]  # fmt: skip  (check_ranges, key_of, setting: from nbv.utils.fields, used with the rest)


def _config_type(kind: Any) -> Any:
    """The type OmegaConf holds for a settings field's type.

    Path -> str, tuples -> lists, nested settings -> their schema; a union that OmegaConf does
    not hold (other than ``X | None``) -> Any.
    """
    args = _union_args(kind)
    if args is not None:
        rest = [a for a in args if a is not type(None)]
        if len(rest) == 1:
            inner = _config_type(rest[0])
            return Any if inner is Any else inner | None
        return Any
    if kind is Path:
        return str
    if _is_settings(kind):
        return schema(kind)
    origin = typing.get_origin(kind)
    if origin is tuple:
        items = [a for a in typing.get_args(kind) if a is not Ellipsis]
        item = items[0] if items and all(a == items[0] for a in items) else Any
        return list[_config_type(item)]
    if origin is list:
        return list[_config_type(typing.get_args(kind)[0])]
    if origin is dict:
        k, v = typing.get_args(kind)
        return dict[k, _config_type(v)]
    return kind


def _default_of(f: dataclasses.Field) -> Any:
    """The field's default as the YAML holds it, or MISSING."""
    if "config_default" in f.metadata:
        return f.metadata["config_default"]
    if f.default is not dataclasses.MISSING:
        value = f.default
    elif f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
    else:
        return MISSING
    if "config" in f.metadata:
        return MISSING  # a field with its own YAML form names that form's default
    return plain(value)


def _instance(node: type, values: Mapping[str, Any]) -> Any:
    """A schema dataclass holding ``values`` (a group's default), its own groups made alike."""
    kwargs = {}
    for f in dataclasses.fields(node):
        if f.name in values:
            value = values[f.name]
            if _is_settings(f.type) and isinstance(value, dict):
                value = _instance(f.type, value)
            kwargs[f.name] = copy.deepcopy(value)
    return node(**kwargs)


def _own_defaults(f: dataclasses.Field, kind: Any) -> bool:
    """A group whose default is its class's own default: its schema's defaults say the same,
    written the YAML's way (a field with its own YAML form, like a camera, cannot be written
    back from the settings' value)."""
    if not _is_settings(kind) or "config" in f.metadata or "config_default" in f.metadata:
        return False
    if f.default_factory is dataclasses.MISSING:
        return False
    try:
        return f.default_factory() == kind()
    except TypeError:  # a group with a required key
        return False


def _schema_field(f: dataclasses.Field, kind: Any) -> tuple[str, Any, Any]:
    ctype = f.metadata.get("config") or _config_type(kind)
    if _own_defaults(f, kind):
        return key_of(f), ctype, dataclasses.field(default_factory=ctype)
    default = _default_of(f)
    if _is_settings(ctype) and isinstance(default, dict):
        return (
            key_of(f),
            ctype,
            dataclasses.field(default_factory=lambda: _instance(ctype, default)),
        )
    if isinstance(default, dict | list):
        return key_of(f), ctype, dataclasses.field(default_factory=lambda: copy.deepcopy(default))
    return key_of(f), ctype, dataclasses.field(default=default)


@functools.cache
def schema(settings: type, extra: tuple[tuple[str, type], ...] = ()) -> type:
    """The structured-config dataclass of a settings dataclass (cached: one class per settings).

    Every ``__init__`` field of ``settings`` becomes a key of the same name (or its ``key``),
    with the type OmegaConf holds and the same default (a required field is MISSING).

    Args:
        settings: the frozen settings dataclass.
        extra: more keys ``(name, schema)``, for the shared groups the YAML composes and
            interpolates but the settings do not hold (``paths``, ``protocol``).
    """
    hints = typing.get_type_hints(settings)
    fields = [_schema_field(f, hints[f.name]) for f in fields_of(settings)]
    fields += [(name, kind, dataclasses.field(default_factory=kind)) for name, kind in extra]
    return dataclasses.make_dataclass(f"{settings.__name__}Config", fields)


@dataclass(frozen=True)
class Entry:
    """An entry point's settings: its settings class and the shared groups its YAML composes.

    Made once in the entry point's config module, it registers the derived schema in hydra's
    ConfigStore as ``schema_name`` (the first entry of the YAML's defaults list), and
    :meth:`build` turns a composed config into the settings object.

    Attributes:
        schema_name: the ConfigStore name (``export_schema``).
        settings: the frozen settings dataclass, nested like the YAML.
        extra: ``(key, schema)`` of the shared groups (``paths``, ``protocol``, ``camera``) the
            YAML composes and interpolates but the settings do not hold.
    """

    schema_name: str
    settings: type
    extra: tuple[tuple[str, type], ...] = ()

    def __post_init__(self) -> None:
        register(self.schema_name, self.schema)

    @property
    def schema(self) -> type:
        """The structured-config dataclass hydra checks the YAML against."""
        return schema(self.settings, self.extra)

    def build(self, cfg: Any) -> Any:
        """The settings of a composed config (:func:`build`)."""
        return build(self.settings, cfg, dict(self.extra))


def build(settings: type, cfg: Any, extra: Mapping[str, type] | None = None) -> Any:
    """The settings object of a composed config (or a plain dict), every key checked.

    Args:
        settings: the frozen settings dataclass.
        cfg: the composed hydra config; its ``hydra`` node and the ``extra`` groups are ignored.
        extra: the shared groups the config holds beside the settings' keys (as :func:`schema`).

    Raises:
        ConfigError: an unknown key, a value of the wrong type, out of range or not fitting
            another (the message names the key path).
    """
    values = validated(schema(settings, tuple((extra or {}).items())), cfg)
    return construct(settings, values)


def as_config(obj: Any) -> dict:
    """A settings object as the dict its YAML would hold (every key, nested)."""
    return plain(obj)
