"""``python -m nbv.dataset [key=value ...]``: generate (or resume) a dataset shard and its samples.

Settings: ``conf/dataset.yaml`` (declared by :class:`nbv.dataset.config.Settings`). On SLURM:
``python -m nbv.dataset -m hydra/launcher=slurm num_shards=4 shard=0,1,2,3`` (one array task per
shard) or ``scripts/slurm_dataset.sbatch``. A refused setting, catalogue or viewspace, and a shard
of which no model could be made (every mesh unreadable, say), ends with one line on stderr and exit
status 2 (:mod:`nbv.config.cli`).
"""

import sys

from nbv.config.cli import command
from nbv.dataset.config import ENTRY

PROG = "nbv.dataset"


def start(cfg) -> int:
    """Build the settings and run the shard: the exit status of :func:`nbv.dataset.generator.run`.

    The work runs here, not in a ``finish``: a ``ValueError`` it raises (a catalogue, a viewspace,
    a folder made with other settings) refuses the run like a bad setting.
    """
    from nbv.dataset.generator import run

    settings = ENTRY.build(cfg)
    return run(settings, settings.sample_settings())


def finish(status: int) -> None:
    if status:
        sys.exit(status)


main = command(PROG, "dataset", start, finish)

if __name__ == "__main__":
    main()
