"""``python -m train [fold=K] [score=coverage|vig] [model=pcnbv|pcnbv_sph] [key=value ...]``.

The 8-fold sweep: ``python -m train -m fold=0,1,2,3,4,5,6,7 score=coverage,vig
model=pcnbv,pcnbv_sph`` (add ``hydra/launcher=slurm`` to run it as a SLURM job array). Settings:
``conf/train.yaml`` (declared by :class:`train.config.TrainSettings`). The final metrics go to
stdout as JSON; a refused setting, a missing input or a run that cannot resume ends with one line
on stderr and exit status 2, and leaves no run folder behind (:mod:`nbv.config.cli`).
"""

import dataclasses
import json
import logging
from pathlib import Path

from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode

from nbv.config.cli import command
from nbv.utils.atomic import write_text
from nbv.utils.lock import one_writer
from train.config import ENTRY, TrainSettings

PROG = "train"
#: Written into hydra's job folder before training: where the run folder is (train.summary).
RUN_FILE = "run.json"

# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("train")


def start(cfg) -> tuple[TrainSettings, dict]:
    """The settings, then the training itself: what stops it before it has written anything
    (bad settings, missing samples, unusable checkpoints, a run that cannot resume) raises
    ValueError and refuses the run."""
    settings = ENTRY.build(cfg)
    hc = HydraConfig.get()
    job_dir = Path(hc.runtime.output_dir)
    given = any(o.split("=", 1)[0].lstrip("+~") == "out_dir" for o in hc.overrides.task)
    if hc.mode == RunMode.MULTIRUN and not given:
        # The default out_dir has no time in it: two sweeps would resume each other's runs.
        settings = dataclasses.replace(settings, out_dir=job_dir)
    # torch loads only for a run that goes ahead: a refused one answers at once.
    from train.loop import run

    # Point hydra's job folder at the run folder, so `train.summary folder=<sweep dir>` finds it.
    job_dir.mkdir(parents=True, exist_ok=True)
    pointer, text = job_dir / RUN_FILE, json.dumps({"out_dir": str(settings.out_dir.resolve())})
    if not pointer.is_file() or pointer.read_text() != text:  # a resumed run's stays as it was
        write_text(pointer, text)
    with one_writer(settings.out_dir, "training run folder"):
        return settings, run(settings)


def finish(started: tuple[TrainSettings, dict]) -> None:
    settings, result = started
    log.info(
        "fold %d (%s held out), %s on %s: done in %s",
        settings.fold, settings.held_out, settings.model.name, settings.score.name,
        settings.out_dir.resolve(),
    )  # fmt: skip
    print(json.dumps({k: v for k, v in result.items() if k != "reference"}, indent=1))


main = command(PROG, "train", start, finish, scratch=(RUN_FILE,))

if __name__ == "__main__":
    main()
