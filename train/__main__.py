"""``python -m train [fold=K] [score=coverage|vig] [model=pcnbv|pcnbv_sph] [key=value ...]``.

The 8-fold sweep: ``python -m train -m fold=0,1,2,3,4,5,6,7 score=coverage,vig
model=pcnbv,pcnbv_sph`` (add ``hydra/launcher=slurm`` to run it as a SLURM job array).
"""

import json
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from train.config import settings_from_config


@hydra.main(config_path="../conf", config_name="train", version_base="1.3")
def main(cfg: DictConfig) -> None:
    from train.loop import run

    try:
        settings = settings_from_config(cfg)
        # Point hydra's job folder at the run folder, so `train.summary <sweep dir>` finds it.
        job_dir = Path(HydraConfig.get().runtime.output_dir)
        job_dir.mkdir(parents=True, exist_ok=True)
        (job_dir / "run.json").write_text(json.dumps({"out_dir": str(settings.out_dir.resolve())}))
        result = run(settings)
    except ValueError as err:  # bad settings, missing samples, unusable checkpoints
        print(f"train: {err}", file=sys.stderr)
        sys.exit(2)
    print(json.dumps({k: v for k, v in result.items() if k != "reference"}, indent=1))


if __name__ == "__main__":
    main()
