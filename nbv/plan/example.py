"""``python -m nbv.plan.example out=OUT.obj [category=chair] [seed=0]``: a synthetic model as a
mesh file, the object of the worked example of planning for your own object.

The model is the first of its category in the built-in synthetic catalogue
(:mod:`nbv.assets.synthetic`), built with ``seed``; the file (any suffix trimesh writes: obj, ply,
stl, off, glb) is written whole or not at all. Settings: ``conf/plan_example.yaml`` (declared by
:class:`ExampleSettings`); a refused setting ends with one line on stderr and exit status 2, and
leaves no run folder behind (:mod:`nbv.config.cli`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import trimesh

from nbv.assets.synthetic import build, catalogue
from nbv.config.cli import command
from nbv.config.schema import PathsConfig
from nbv.config.settings import Entry, check_ranges, setting
from nbv.utils.atomic import fsync_replace

PROG = "nbv.plan.example"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.plan.example")

#: The mesh files the example may be written as (trimesh picks the format by the suffix).
SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb")
#: The synthetic catalogue's categories, sorted.
CATEGORIES = tuple(sorted({e.category for e in catalogue()}))
_ONE_OF = f"one of {', '.join(CATEGORIES)}"


@dataclass(frozen=True)
class ExampleSettings:
    """What ``python -m nbv.plan.example`` writes (``conf/plan_example.yaml``).

    Attributes:
        out: the mesh file to write, ending in .obj, .ply, .stl, .off or .glb (required).
        category: a category of the synthetic catalogue (:data:`CATEGORIES`); its first model
            is written.
        seed: the model's seed.
    """

    out: Path = setting(
        check=lambda p: p.suffix.lower() in SUFFIXES,
        allowed="a mesh file ending in " + ", ".join(SUFFIXES[:-1]) + f" or {SUFFIXES[-1]}",
    )
    category: str = setting("chair", check=lambda c: c in CATEGORIES, allowed=_ONE_OF)
    seed: int = 0

    def __post_init__(self) -> None:
        check_ranges(self)


ENTRY = Entry("plan_example_schema", ExampleSettings, extra=(("paths", PathsConfig),))


def write_example(path: Path, category: str = "chair", seed: int = 0) -> Path:
    """Write the first synthetic model of ``category`` to ``path``; returns ``path``.

    Raises:
        ValueError: an unknown category (the message lists them).
    """
    entry = next((e for e in catalogue() if e.category == category), None)
    if entry is None:
        raise ValueError(f"category={category!r}: must be {_ONE_OF}")
    vertices, faces = build(entry, seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    # trimesh picks the format by the suffix, so the temporary file keeps it.
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    try:
        trimesh.Trimesh(vertices, faces, process=False).export(tmp)
        fsync_replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def finish(settings: ExampleSettings) -> None:
    write_example(settings.out, settings.category, settings.seed)
    log.info("wrote %s", settings.out)


main = command(PROG, "plan_example", ENTRY.build, finish)

if __name__ == "__main__":
    main()
