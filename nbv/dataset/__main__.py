"""``python -m nbv.dataset [key=value ...]``: generate (or resume) a dataset shard and its samples.

Settings: ``conf/dataset.yaml`` (schema: :mod:`nbv.dataset.config`). On SLURM: ``python -m
nbv.dataset -m hydra/launcher=slurm num_shards=4 shard=0,1,2,3`` (one array task per shard) or
``scripts/slurm_dataset.sbatch``. A refused setting ends with one line on stderr and exit status 2,
and leaves no run folder behind (:mod:`nbv.config.cli`).
"""

import sys

import hydra
from omegaconf import DictConfig

from nbv.config.cli import entry_point, refuse
from nbv.dataset.config import sample_settings_from_config, settings_from_config
from nbv.dataset.generate import run

PROG = "nbv.dataset"


@hydra.main(config_path="../../conf", config_name="dataset", version_base="1.3")
def main(cfg: DictConfig) -> None:
    try:
        settings = settings_from_config(cfg)
        sample_settings = sample_settings_from_config(cfg)
        status = run(settings, sample_settings)
    except ValueError as err:  # bad settings, catalogues, viewspaces: one clear line
        refuse(PROG, err)
    if status:
        sys.exit(status)


if __name__ == "__main__":
    entry_point(PROG, main)
