"""``python -m nbv.bench [checkpoint=PATH] [network=false] [render=false] [json=PATH]``.

Prints one table of the fast paths against plain references (:mod:`nbv.bench.suite`) on stdout,
then the ground-truth hull check when the dataset exists. Settings: ``conf/bench.yaml``
(declared by :class:`nbv.bench.config.BenchSettings`). A refused setting ends with one line on
stderr and exit status 2, and leaves no run folder behind (:mod:`nbv.config.cli`).
"""

import json
import logging

from nbv.models.threads import configure_openmp

# Torch's OpenMP threads sleep when idle, so a busy machine slows the network rows ~1.1-1.9x,
# not 4-11x (nbv.models.threads); set before anything imports torch.
configure_openmp()

from nbv.bench.config import ENTRY, BenchSettings  # noqa: E402
from nbv.config.cli import command  # noqa: E402
from nbv.utils.atomic import write_text  # noqa: E402

PROG = "nbv.bench"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.bench")


def finish(settings: BenchSettings) -> None:
    """Time every row, print the table and the hull check, write the JSON."""
    from nbv.bench.suite import SMALL_GT, format_table, run, small_gt_hull_error
    from nbv.geometry.scores import DEFAULT_N_GT

    if settings.network:
        log.info("episode row: %s", settings.checkpoint or "untrained weights")
    rows = run(render=settings.render, network=settings.network, checkpoint=settings.checkpoint)
    print(format_table(rows))
    if settings.dataset.exists():
        e = small_gt_hull_error(settings.dataset)
        print(
            f"\nHull volume of a {SMALL_GT}-point ground truth vs {DEFAULT_N_GT} points "
            f"({e['models']} models of {settings.dataset}): {100 * e['mean']:.1f}% smaller on "
            f"average (median {100 * e['median']:.1f}%, worst {100 * e['worst']:.1f}%)."
        )
    if settings.json:
        settings.json.parent.mkdir(parents=True, exist_ok=True)
        write_text(settings.json, json.dumps(rows, indent=1))
        log.info("wrote %s", settings.json)


main = command(PROG, "bench", ENTRY.build, finish)

if __name__ == "__main__":
    main()
