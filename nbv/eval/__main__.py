"""``python -m nbv.eval [methods=[...]] [dataset=unseen|test|meshes] [viewspace=...] [key=value]``.

Settings: ``conf/eval.yaml`` (declared by :class:`nbv.eval.config.EvalSettings`). Writes
``outputs/eval/<run>/``: results.json, summary.csv, report.md and the PNG plots. A refused
setting or input (a missing dataset, a start view outside it) ends with one line on stderr and
exit status 2, and leaves no run folder behind (:mod:`nbv.config.cli`).
"""

import logging

from nbv.models.threads import configure_openmp

# Before torch is imported: OpenMP threads that sleep when idle, so that a machine busy with
# other work does not make every forward pass wait for spinning threads (nbv.models.threads).
configure_openmp()

from pathlib import Path  # noqa: E402

from nbv.config.cli import check_given_files, command  # noqa: E402
from nbv.eval.config import ENTRY  # noqa: E402

PROG = "nbv.eval"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.eval")


def start(cfg) -> Path:
    """Build the settings and run the evaluation. The whole run is here, as it always was: a
    ValueError it raises (a bad setting, a missing or unusable dataset or scorer file) refuses
    the run, and the run folder goes when the run left nothing of its own there."""
    from nbv.eval.evaluate import run
    from nbv.policies.registry import networks_of
    from nbv.utils.lock import one_writer

    settings = ENTRY.build(cfg)
    check_given_files({f"checkpoints.{m}": settings.checkpoints.get(m)
                       for m in networks_of(settings.methods)})  # fmt: skip
    with one_writer(settings.out_dir, "evaluation run"):
        return run(settings)


def finish(out: Path) -> None:
    log.info("wrote %s, results.json, summary.csv and the plots", out / "report.md")


main = command(PROG, "eval", start, finish)

if __name__ == "__main__":
    main()
