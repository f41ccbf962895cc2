"""``python -m nbv.eval [methods=[...]] [dataset=unseen|test|meshes] [viewspace=...] [key=value]``.

Settings: ``conf/eval.yaml``. Writes ``outputs/eval/<run>/``: results.json, summary.csv,
report.md and the PNG plots.
"""

import sys

import hydra
from omegaconf import DictConfig

from nbv.eval.config import settings_from_config


@hydra.main(config_path="../../conf", config_name="eval", version_base="1.3")
def main(cfg: DictConfig) -> None:
    from nbv.eval.evaluate import run

    try:
        settings = settings_from_config(cfg)
        out = run(settings)
    except ValueError as err:  # bad settings, missing datasets: one clear line
        print(f"nbv.eval: {err}", file=sys.stderr)
        sys.exit(2)
    print(f"nbv.eval: wrote {out / 'report.md'}, results.json, summary.csv and the plots")


if __name__ == "__main__":
    main()
