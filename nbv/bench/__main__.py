"""``python -m nbv.bench [checkpoint=PATH] [network=false] [render=false] [json=PATH]``.

Prints one table of the fast paths against plain references (:mod:`nbv.bench.suite`) on stdout,
then the ground-truth hull check when the dataset exists. Settings: ``conf/bench.yaml`` (schema:
:mod:`nbv.bench.config`). A refused setting ends with one line on stderr and exit status 2, and
leaves no run folder behind (:mod:`nbv.config.cli`).
"""

import json
import logging

import hydra
from omegaconf import DictConfig

from nbv.bench.config import settings_from_config
from nbv.config.cli import entry_point, refuse

PROG = "nbv.bench"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.bench")


@hydra.main(config_path="../../conf", config_name="bench", version_base="1.3")
def main(cfg: DictConfig) -> None:
    try:
        settings = settings_from_config(cfg)
    except ValueError as err:
        refuse(PROG, err)
    from nbv.bench.suite import format_table, run, small_gt_hull_error

    if settings.network:
        log.info("episode row: %s", settings.checkpoint or "untrained weights")
    rows = run(render=settings.render, network=settings.network, checkpoint=settings.checkpoint)
    print(format_table(rows))
    if settings.dataset.exists():
        e = small_gt_hull_error(settings.dataset)
        print(
            f"\nHull volume of a 512-point ground truth vs 16384 points ({e['models']} models of "
            f"{settings.dataset}): {100 * e['mean']:.1f}% smaller on average (median "
            f"{100 * e['median']:.1f}%, worst {100 * e['worst']:.1f}%)."
        )
    if settings.json:
        settings.json.parent.mkdir(parents=True, exist_ok=True)
        settings.json.write_text(json.dumps(rows, indent=1))
        log.info("wrote %s", settings.json)


if __name__ == "__main__":
    entry_point(PROG, main)
