"""``python -m nbv.eval [methods=[...]] [dataset=unseen|test|meshes] [viewspace=...] [key=value]``.

Settings: ``conf/eval.yaml``. Writes ``outputs/eval/<run>/``: results.json, summary.csv,
report.md and the PNG plots.
"""

import os
import sys

# Torch's OpenMP threads spin while they wait. On a 2-core machine shared with other work that
# made a PCNBV forward pass over 3x slower (measured under load: 0.69 s spinning, 0.21 s
# passive); on idle cores passive waiting costs about 5 % (0.082 s -> 0.088 s). Set before
# torch is imported; an explicit OMP_WAIT_POLICY in the environment wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import hydra  # noqa: E402
from omegaconf import DictConfig  # noqa: E402

from nbv.eval.config import settings_from_config  # noqa: E402


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
