"""A tiny hydra app for the SLURM launcher test: each job writes where and how SLURM ran it.

    python tests/slurm/hello_app.py -m hydra/launcher=slurm_test \
        hydra.searchpath=[file://<repo>/conf] x=0,1

writes ``<job output dir>/result.json`` with ``x`` and the SLURM job, array job and array task
ids (null when not run by SLURM). ``slurm_test`` extends the project's launcher
``conf/hydra/launcher/slurm.yaml``, which the search path makes visible.
"""

import json
import os
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig


@hydra.main(version_base="1.3", config_path="conf", config_name="hello")
def main(cfg: DictConfig) -> None:
    """Write ``result.json`` into this job's hydra output directory."""
    result = {
        "x": cfg.x,
        "job_id": os.environ.get("SLURM_JOB_ID"),
        "array_job_id": os.environ.get("SLURM_ARRAY_JOB_ID"),
        "array_task_id": os.environ.get("SLURM_ARRAY_TASK_ID"),
    }
    out = Path(HydraConfig.get().runtime.output_dir) / "result.json"
    out.write_text(json.dumps(result))


if __name__ == "__main__":
    main()
