"""``python -m nbv.export eval_run=outputs/eval/<run>`` or ``python -m nbv.export data_dir=...``.

Writes PC-NBV's file layout (:mod:`nbv.export.pcnbv_format`) into ``out_dir``. Settings:
``conf/export.yaml`` (declared by :class:`nbv.export.config.ExportSettings`). The settings and
the source's files are checked before anything is written (the dataset gives its full
views; every model has an episode from every start view); a refused export ends with one line
on stderr and exit status 2, and leaves no folder behind (:mod:`nbv.config.cli`).
"""

import logging

from nbv.config.cli import command
from nbv.export.config import ENTRY

PROG = "nbv.export"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.export")


def start(cfg) -> tuple:
    """The settings and the source, checked: nothing is written yet."""
    from nbv.export.pcnbv_format import check_complete, check_destination
    from nbv.export.sources import from_dataset, from_eval_run

    s = ENTRY.build(cfg)
    check_destination(s.out_dir)
    if s.eval_run is not None:
        sources, selections = from_eval_run(s.eval_run, s.viewspaces, s.methods, s.limit)
        origin = {"eval_run": str(s.eval_run)}
    else:
        sources, selections = from_dataset(s.data_dir, s.viewspaces, s.limit), []
        origin = {"data_dir": str(s.data_dir)}
    check_complete(sources, selections)
    for source in sources:  # a bad model refuses the export before anything is written
        source.dataset.verify(source.keys)
    return s, sources, selections, origin


def finish(started: tuple) -> None:
    from nbv.export.pcnbv_format import export
    from nbv.utils.lock import one_writer

    s, sources, selections, origin = started
    with one_writer(s.out_dir, "export"):
        export(s.out_dir, sources, selections, ascii=s.ascii, origin=origin, progress=s.progress)
    log.info("wrote %s", s.out_dir / "manifest.json")


main = command(PROG, "export", start, finish)

if __name__ == "__main__":
    main()
