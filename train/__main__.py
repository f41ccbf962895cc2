"""``python -m train [fold=K] [score=coverage|vig] [model=pcnbv|pcnbv_sph] [key=value ...]``.

The 8-fold sweep: ``python -m train -m fold=0,1,2,3,4,5,6,7 score=coverage,vig
model=pcnbv,pcnbv_sph`` (add ``hydra/launcher=slurm`` to run it as a SLURM job array). Settings:
``conf/train.yaml`` (schema: :mod:`train.config`). The final metrics go to stdout as JSON; a
refused setting ends with one line on stderr and exit status 2, and leaves no run folder behind
(:mod:`nbv.config.cli`).
"""

import dataclasses
import json
import logging
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from nbv.config.cli import entry_point, refuse
from train.config import settings_from_config

PROG = "train"
#: Written into hydra's job folder before training: where the run folder is (train.summary).
RUN_FILE = "run.json"

# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("train")


@hydra.main(config_path="../conf", config_name="train", version_base="1.3")
def main(cfg: DictConfig) -> None:
    try:
        settings = settings_from_config(cfg)
        hc = HydraConfig.get()
        job_dir = Path(hc.runtime.output_dir)
        given = any(o.split("=", 1)[0].lstrip("+~") == "out_dir" for o in hc.overrides.task)
        if hc.mode == RunMode.MULTIRUN and not given:
            # The default out_dir has no time in it: two sweeps would resume each other's runs.
            settings = dataclasses.replace(settings, out_dir=job_dir)
        # torch loads only for a run that goes ahead: a refused one answers at once.
        from train.loop import run

        # Point hydra's job folder at the run folder, so `train.summary <sweep dir>` finds it.
        job_dir.mkdir(parents=True, exist_ok=True)
        out_dir = str(settings.out_dir.resolve())
        (job_dir / RUN_FILE).write_text(json.dumps({"out_dir": out_dir}))
        result = run(settings)
    except ValueError as err:  # bad settings, missing samples, unusable checkpoints
        refuse(PROG, err, scratch=(RUN_FILE,))
    log.info(
        "fold %d (%s held out), %s on %s: done in %s",
        settings.fold, settings.held_out, settings.model_name, settings.score, out_dir,
    )  # fmt: skip
    print(json.dumps({k: v for k, v in result.items() if k != "reference"}, indent=1))


if __name__ == "__main__":
    entry_point(PROG, main)
