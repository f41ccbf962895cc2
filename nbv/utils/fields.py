"""Settings fields that carry their allowed range: :func:`setting` and :func:`check_ranges`.

A frozen settings dataclass declares each field once, with its type, default and (in the field's
metadata) what values it allows; ``__post_init__`` calls :func:`check_ranges`. The hydra side
(:mod:`nbv.config.settings`) reads the same metadata to derive the schema and to name a bad
value's key path, so the library's own settings (the planners', the map's) are checked the same
way whether they come from a config or from code.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any


class ConfigError(ValueError):
    """A setting that cannot be used; the message names the key and what is allowed."""


def setting(
    default: Any = dataclasses.MISSING,
    *,
    factory: Callable[[], Any] | None = None,
    check: Callable[[Any], bool] | None = None,
    allowed: str | None = None,
    key: str | None = None,
    config: Any = None,
    convert: Callable[[Any], Any] | None = None,
    config_default: Any = dataclasses.MISSING,
) -> Any:
    """A settings field with its range and, where needed, its YAML form.

    Args:
        default: the default value (omit for a required key).
        factory: a default factory instead of ``default`` (for mutable or nested defaults).
        check: True for an allowed value (null is passed too when the type allows it).
        allowed: what ``check`` allows, in words (``"an integer >= 1"``).
        key: the YAML key, when it is not the field's name.
        config: the type the YAML value has, when the field's type is not one OmegaConf holds.
        convert: YAML value -> field value (with ``config``).
        config_default: the YAML value's default (with ``config``), when the field has one.
    """
    if (check is None) != (allowed is None):
        raise TypeError("setting(): give check and allowed together")
    metadata = {
        name: value
        for name, value in (
            ("check", check),
            ("allowed", allowed),
            ("key", key),
            ("config", config),
            ("convert", convert),
        )
        if value is not None
    }
    if config_default is not dataclasses.MISSING:
        metadata["config_default"] = config_default
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def fields_of(settings: type) -> list[dataclasses.Field]:
    """The fields a config sets: those made by ``__init__``."""
    return [f for f in dataclasses.fields(settings) if f.init]


def key_of(f: dataclasses.Field) -> str:
    """The YAML key of a settings field."""
    return f.metadata.get("key", f.name)


def check(f: dataclasses.Field, value: Any, prefix: str = "") -> None:
    """Refuse ``value`` for field ``f`` when its metadata's ``check`` does not allow it.

    Raises:
        ConfigError: ``<prefix><key>=<value>: must be <allowed>`` (tuples shown as lists,
            paths as strings: as the YAML writes them).
    """
    allows = f.metadata.get("check")
    if allows is not None and not allows(value):
        shown = list(value) if isinstance(value, tuple) else value
        if isinstance(shown, Path):
            shown = str(shown)
        raise ConfigError(f"{prefix}{key_of(f)}={shown!r}: must be {f.metadata['allowed']}")


def check_ranges(obj: Any) -> None:
    """Check each field of a settings object against its ``check`` (call in ``__post_init__``).

    Raises:
        ConfigError: ``<key>=<value>: must be <allowed>`` for the first field out of range.
    """
    for f in fields_of(type(obj)):
        check(f, getattr(obj, f.name))
