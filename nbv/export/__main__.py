"""``python -m nbv.export eval_run=outputs/eval/<run>`` or ``python -m nbv.export data_dir=...``.

Writes PC-NBV's file layout (:mod:`nbv.export.pcnbv_format`) into ``out_dir``. Settings:
``conf/export.yaml`` (schema: :mod:`nbv.export.config`). The settings and the source's files are
checked before anything is written; a refused export ends with one line on stderr and exit
status 2, and leaves no folder behind (:mod:`nbv.config.cli`).
"""

import logging

import hydra
from omegaconf import DictConfig

from nbv.config.cli import entry_point, refuse
from nbv.export.config import settings_from_config

PROG = "nbv.export"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.export")


@hydra.main(config_path="../../conf", config_name="export", version_base="1.3")
def main(cfg: DictConfig) -> None:
    from nbv.export.pcnbv_format import check_destination, export
    from nbv.export.sources import from_dataset, from_eval_run

    try:
        s = settings_from_config(cfg)
        check_destination(s.out_dir)
        if s.eval_run is not None:
            sources, selections = from_eval_run(s.eval_run, s.viewspaces, s.methods, s.limit)
            origin = {"eval_run": str(s.eval_run)}
        else:
            sources, selections = from_dataset(s.data_dir, s.viewspaces, s.limit), []
            origin = {"data_dir": str(s.data_dir)}
    except ValueError as err:  # bad settings or source files: one clear line, nothing written
        refuse(PROG, err)
    export(s.out_dir, sources, selections, ascii=s.ascii, origin=origin, progress=s.progress)
    log.info("wrote %s", s.out_dir / "manifest.json")


if __name__ == "__main__":
    entry_point(PROG, main)
