"""``python -m nbv.plan.example OUT.obj [--category chair] [--seed 0]``: a synthetic model as a
mesh file, the object of the README's worked example (``Planning for your own object``).

The model is the first of its category in the built-in synthetic catalogue
(:mod:`nbv.assets.synthetic`), built with ``--seed``; the file (any suffix trimesh writes: obj,
ply, stl, off, glb) is written whole or not at all.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

import trimesh

from nbv.assets.synthetic import build, catalogue
from nbv.utils.atomic import fsync_replace

log = logging.getLogger("nbv.plan.example")


def write_example(path: Path, category: str = "chair", seed: int = 0) -> Path:
    """Write the first synthetic model of ``category`` to ``path``; returns ``path``.

    Raises:
        ValueError: an unknown category (the message lists them).
    """
    entries = catalogue()
    entry = next((e for e in entries if e.category == category), None)
    if entry is None:
        names = sorted({e.category for e in entries})
        raise ValueError(f"--category {category!r}: allowed: {', '.join(names)}")
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


def main(argv: Sequence[str] | None = None) -> int:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = argparse.ArgumentParser(
        prog="python -m nbv.plan.example", description="Write a synthetic model as a mesh file."
    )
    parser.add_argument("out", type=Path, help="mesh file to write (.obj, .ply, .stl, .off, .glb)")
    parser.add_argument("--category", default="chair", help="synthetic category (default chair)")
    parser.add_argument("--seed", type=int, default=0, help="model seed (default 0)")
    args = parser.parse_args(argv)
    if args.out.suffix.lower() not in (".obj", ".ply", ".stl", ".off", ".glb"):
        parser.error(f"{args.out}: the suffix must be .obj, .ply, .stl, .off or .glb")
    try:
        write_example(args.out, args.category, args.seed)
    except ValueError as err:
        parser.error(str(err))
    log.info("wrote %s", args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
