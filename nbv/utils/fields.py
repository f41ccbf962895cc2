"""Settings fields that carry their allowed range: :func:`setting` and :func:`check_ranges`.

A frozen settings dataclass declares each field once, with its type, default and (in the field's
metadata) what values it allows; ``__post_init__`` calls :func:`check_ranges`. The hydra side
(:mod:`nbv.config.settings`) reads the same metadata to derive the schema and to name a bad
value's key path, so the library's own settings (the planners', the map's) are checked the same
way whether they come from a config or from code.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Collection
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Allows:
    """What a setting allows: the check and its words, declared once (:func:`at_least`,
    :func:`positive`, :func:`between`, :func:`one_of`, :func:`or_null`)."""

    test: Callable[[Any], bool]
    words: str

    def __call__(self, value: Any) -> bool:
        return bool(self.test(value))


def at_least(low: float, kind: str = "an integer", note: str = "") -> Allows:
    """``value >= low``: "an integer >= 1", "a distance >= 0", "an integer >= 0 (0 = all)"."""
    return Allows(lambda v: v >= low, f"{kind} >= {low}" + (f" ({note})" if note else ""))


def positive(kind: str = "number") -> Allows:
    """``value > 0``: "a positive number", "a positive distance"."""
    return Allows(lambda v: v > 0, f"a positive {kind}")


def between(low: float, high: float, closed: str = "[]") -> Allows:
    """``low <= value <= high``; ``closed`` says which ends belong ("[]", "()", "[)", "(]"), and
    the words are the interval: "in [0, 1]", "in (0.5, 1)"."""
    if len(closed) != 2 or closed[0] not in "[(" or closed[1] not in "])":
        raise ValueError(f"between(): closed={closed!r}: must be two of [ ( and ] )")
    above = (lambda v: v >= low) if closed[0] == "[" else (lambda v: v > low)
    below = (lambda v: v <= high) if closed[1] == "]" else (lambda v: v < high)
    return Allows(lambda v: above(v) and below(v), f"in {closed[0]}{low}, {high}{closed[1]}")


def one_of(names: Collection[str], hint: str = "") -> Allows:
    """``value in names``: "one of a, b, c" (and ``hint``, written right after). ``names`` is
    read when a value is checked: a dict of declarations may gain rows later."""
    return Allows(lambda v: v in names, f"one of {', '.join(names)}{hint}")


def or_null(allows: Allows) -> Allows:
    """None, or what ``allows`` allows: "null or an integer >= 1"."""
    return Allows(lambda v: v is None or allows(v), f"null or {allows.words}")


class ConfigError(ValueError):
    """A setting that cannot be used; the message names the key and what is allowed."""


#: Config keys that were renamed: old -> new (docs/journal.md, "Renames of the third
#: restructuring"). An old key is refused with one line naming the new one.
RENAMED_KEYS = {"hull": "setcover", "ig": "infogain"}


def renamed_line(key: str) -> str | None:
    """The refusal of a key path under a renamed key (``hull.dilate: renamed: give
    setcover.dilate``); None for any other key."""
    head, _, rest = str(key).partition(".")
    if head not in RENAMED_KEYS:
        return None
    new = RENAMED_KEYS[head]
    return f"{key}: renamed: give {new}.{rest}" if rest else f"{key}: renamed {new}"


def setting(
    default: Any = dataclasses.MISSING,
    *,
    factory: Callable[[], Any] | None = None,
    allows: Allows | None = None,
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
        allows: what the field allows, check and words together (:class:`Allows`); ``check``
            and ``allowed`` are the same spelled apart, for a rule the vocabulary lacks.
        check: True for an allowed value (null is passed too when the type allows it).
        allowed: what ``check`` allows, in words (``"an integer >= 1"``).
        key: the YAML key, when it is not the field's name.
        config: the type the YAML value has, when the field's type is not one OmegaConf holds.
        convert: YAML value -> field value (with ``config``).
        config_default: the YAML value's default (with ``config``), when the field has one.
    """
    if (check is None) != (allowed is None):
        raise TypeError("setting(): give check and allowed together")
    if allows is not None:
        if check is not None:
            raise TypeError("setting(): give allows, or check and allowed, not both")
        check, allowed = allows, allows.words
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
