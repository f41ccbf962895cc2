"""Developer tool: time the depth renderers, Blender against ray casting, and print the table.

    python scripts/bench_render.py [--views 33] [--threads 2] [--meshes DIR | --no-meshes]
                                   [--binary PATH | --no-binary] [--repeat N]

Renders a 50k-triangle mesh (and every OBJ of ``--meshes``, by default ``../shared/meshes``
beside the checkout when it exists) with both backends (:func:`nbv.bench.render.benchmark`);
``python -m nbv.bench`` runs the same measurement for its rendering rows.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from nbv.bench.render import DEFAULT_BINARY, benchmark, format_table

#: Development meshes beside a checkout (not part of the project), used when present.
SHARED_MESHES = Path(__file__).resolve().parents[2] / "shared" / "meshes"


def main(argv: list[str] | None = None) -> None:
    """Parse the options, run the benchmark, print its table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--views", type=int, default=33)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument(
        "--meshes",
        type=Path,
        default=SHARED_MESHES if SHARED_MESHES.is_dir() else None,
        help=f"folder of .obj files to add (default: {SHARED_MESHES} when it exists)",
    )
    parser.add_argument("--no-meshes", action="store_true", help="only the bumpy torus")
    parser.add_argument("--blender", default=None, help="Blender executable (default: bpy)")
    parser.add_argument(
        "--binary",
        default=DEFAULT_BINARY,
        help=f"Blender binary timed beside it (default: {DEFAULT_BINARY!r} on the PATH)",
    )
    parser.add_argument("--no-binary", action="store_true", help="skip the binary's rows")
    parser.add_argument("--repeat", type=int, default=1, help="keep the fastest of N runs")
    args = parser.parse_args(argv)
    if args.meshes is not None and not args.meshes.is_dir():
        parser.error(f"--meshes {args.meshes} is not a folder")
    meshes = None if args.no_meshes else args.meshes
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    binary = None if args.no_binary else args.binary
    results = benchmark(
        args.views, args.width, args.height, args.threads, meshes, args.blender, args.repeat, binary
    )
    print(format_table(results))


if __name__ == "__main__":
    main()
