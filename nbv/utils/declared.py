"""Looking a name up in a table of declarations (methods, networks, mesh sources)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TypeVar

T = TypeVar("T")


def look_up(
    table: Mapping[str, T],
    name: str,
    what: str,
    listed: str = "allowed",
    error: type[Exception] = ValueError,
) -> T:
    """``table[name]``.

    Raises:
        ``error``: no such name: ``unknown <what> '<name>'; <listed>: <every name, in order>``.
    """
    if name not in table:
        raise error(f"unknown {what} {name!r}; {listed}: {', '.join(table)}")
    return table[name]
