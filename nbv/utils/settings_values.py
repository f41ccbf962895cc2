"""Settings objects as plain values and back, without hydra: what a library API (the robot's
:class:`nbv.scan.planner.Planner`) needs to take keyword overrides and to save and restore its
settings as JSON.

A settings object is a frozen dataclass whose fields are declared with
:func:`nbv.utils.fields.setting`. :func:`plain` writes it as nested dicts, lists and strings (the
form its YAML holds); :func:`construct` makes one from such a dict, every key given;
:func:`replaced` applies a few keys over an existing object. Both check every range and name a bad
key by its path (``viewspace.n=1: ...``). The commands add hydra's structured config on top
(:mod:`nbv.config.settings`).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from nbv.utils.fields import ConfigError, check, fields_of, key_of, renamed_line


def union_args(kind: Any) -> tuple[Any, ...] | None:
    """The members of a union type (``X | None``), or None for another type."""
    if typing.get_origin(kind) in (typing.Union, types.UnionType):
        return typing.get_args(kind)
    return None


def is_settings(kind: Any) -> bool:
    """Whether ``kind`` is a dataclass type (a settings group)."""
    return isinstance(kind, type) and dataclasses.is_dataclass(kind)


def plain(value: Any) -> Any:
    """A settings value as the YAML would hold it (paths as strings, tuples as lists, settings
    objects as dicts keyed like their YAML)."""
    if isinstance(value, Path):
        return str(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {key_of(f): plain(getattr(value, f.name)) for f in fields_of(type(value))}
    if isinstance(value, tuple | list):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return value


def _tupled(value: Any) -> Any:
    return tuple(_tupled(v) for v in value) if isinstance(value, list) else value


def coerce(kind: Any, value: Any, key: str) -> Any:
    """A plain value as the field's type wants it: str -> Path, list -> tuple, dict -> settings
    (every key given, :func:`construct`)."""
    if value is None:
        return None
    args = union_args(kind)
    if args is not None:
        rest = [a for a in args if a is not type(None)]
        return coerce(rest[0], value, key) if len(rest) == 1 else _tupled(value)
    if kind is Path:
        return Path(value)
    if is_settings(kind):
        return value if isinstance(value, kind) else construct(kind, value, f"{key}.")
    origin = typing.get_origin(kind)
    if origin is tuple:
        items = [a for a in typing.get_args(kind) if a is not Ellipsis]
        return tuple(coerce(items[0] if items else Any, v, key) for v in value)
    if origin is dict:
        inner = typing.get_args(kind)[1]
        return {k: coerce(inner, v, f"{key}.{k}") for k, v in value.items()}
    return value


def _prefixed(err: ValueError, settings: type, prefix: str) -> ConfigError:
    """The error of a nested settings object, its key given the path of the group it is in."""
    message = str(err)
    if prefix and any(
        message.startswith(f"{key_of(f)}=") or message.startswith(f"{key_of(f)}:")
        for f in fields_of(settings)
    ):
        message = prefix + message
    return ConfigError(message)


def _value(f: dataclasses.Field, kind: Any, value: Any, prefix: str) -> Any:
    """One field's value from its plain form (its ``convert``, else :func:`coerce`), checked."""
    key = key_of(f)
    if "convert" in f.metadata:
        try:
            value = f.metadata["convert"](value)
        except ValueError as err:
            message = str(err)
            named = message.startswith((f"{key}=", f"{key}:", f"{prefix}{key}"))
            raise ConfigError(message if named else f"{prefix}{key}: {message}") from None
    else:
        value = coerce(kind, value, prefix + key)
    check(f, value, prefix)
    return value


def construct(settings: type, values: Mapping[str, Any], prefix: str = "") -> Any:
    """The settings object of a plain dict that gives every key (nested groups as dicts).

    Raises:
        ConfigError: a missing key, or a bad value named by its key path.
    """
    hints = typing.get_type_hints(settings)
    kwargs = {}
    for f in fields_of(settings):
        key = key_of(f)
        if key not in values:
            raise ConfigError(f"{prefix}{key}: missing")
        kwargs[f.name] = _value(f, hints[f.name], values[key], prefix)
    try:
        return settings(**kwargs)
    except ValueError as err:
        raise _prefixed(err, settings, prefix) from None


def replaced(obj: Any, overrides: Mapping[str, Any], prefix: str = "") -> Any:
    """``obj`` with some keys replaced: a nested group by a dict of its own keys (the rest kept),
    a value in its plain form or as the field's own type.

    Raises:
        ConfigError: an unknown key (the allowed ones listed), or a bad value named by its key
            path.
    """
    settings = type(obj)
    by_key = {key_of(f): f for f in fields_of(settings)}
    hints = typing.get_type_hints(settings)
    changes = {}
    for key, value in overrides.items():
        f = by_key.get(key)
        if f is None:
            renamed = None if prefix else renamed_line(key)
            raise ConfigError(
                renamed or f"{prefix}{key}: unknown key; allowed: {', '.join(by_key)}"
            )
        current = getattr(obj, f.name)
        if isinstance(value, Mapping) and is_settings(type(current)):
            changes[f.name] = replaced(current, value, f"{prefix}{key}.")
        else:
            changes[f.name] = _value(f, hints[f.name], value, prefix)
    try:
        return dataclasses.replace(obj, **changes)
    except ValueError as err:
        raise _prefixed(err, settings, prefix) from None
