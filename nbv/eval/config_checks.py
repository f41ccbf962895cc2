"""The checks the evaluator's settings share (:mod:`nbv.eval.config`): a list of names, a
viewspace, a nested group's ranges, each refusal one :class:`~nbv.utils.fields.ConfigError` naming
the key path."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from nbv.config.schema import ConfigError, names
from nbv.config.settings import check_ranges, setting
from nbv.geometry.viewspace import is_named

#: What ``viewspace`` may name, as a message lists it.
VIEWSPACE_CHOICES = ("original", "permuted", "sphere_<n>", "hemisphere_<n>", "a file of x y z rows")


def names_setting(label: str, default: tuple[str, ...], key: str | None = None, **kw: Any) -> Any:
    """A field the YAML gives as null, one name or a list of names (a tuple of names here).

    Args:
        label: the key path a bad value's message names (``disturb.checks``).
        default: the field's default; the YAML's default is the same list (``config_default``
            in ``kw`` overrides it, e.g. null for "derived").
        key: the YAML key, when it is not the field's name.
    """
    kw.setdefault("config_default", list(default))
    return setting(default, key=key, config=Any, convert=lambda v: names(v, label), **kw)


def optional_path(value: str | None) -> Path | None:
    """A path the YAML may leave null or empty (both: none)."""
    return Path(value) if value else None


def check_allowed(key: str, values: tuple, allowed: tuple, empty_ok: bool = False) -> None:
    if not values and not empty_ok:
        raise ConfigError(f"{key} is empty; allowed: {', '.join(allowed)}")
    bad = [v for v in values if v not in allowed]
    if bad:
        raise ConfigError(
            f"{key}: unknown {', '.join(map(repr, bad))}; allowed: {', '.join(allowed)}"
        )
    if len(set(values)) != len(values):
        raise ConfigError(f"{key} lists a name twice: {list(values)}")


def check_viewspaces(key: str, values: tuple[str, ...], empty_ok: bool = False) -> None:
    """Refuse a viewspace that is neither a name :func:`~nbv.geometry.viewspace.is_named` knows
    nor a file of ``x y z`` rows, and a list naming one twice."""
    if not values and not empty_ok:
        raise ConfigError(f"{key} is empty; allowed: {', '.join(VIEWSPACE_CHOICES)}")
    bad = [v for v in values if not is_named(v) and not Path(v).is_file()]
    if bad:
        raise ConfigError(
            f"{key}: unknown {', '.join(map(repr, bad))}; allowed: {', '.join(VIEWSPACE_CHOICES)}"
        )
    if len(set(values)) != len(values):
        raise ConfigError(f"{key} lists a name twice: {list(values)}")


def group_ranges(obj: Any, group: str) -> None:
    """:func:`check_ranges` of a nested group, its message naming the key path (``prepare.``):
    the same message whether the settings came from a config or from code."""
    try:
        check_ranges(obj)
    except ConfigError as err:
        raise ConfigError(f"{group}.{err}") from None


def distinct_positive(values: tuple[float, ...]) -> bool:
    return all(x > 0 for x in values) and len(set(values)) == len(values)
