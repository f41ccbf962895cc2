"""The fitting check on a real dataset: can PCNBV (or PCNBV-sph) rank the views of a few models it
is trained on? (A developer tool; :mod:`train.fitcheck`.)

    python scripts/fit_check.py --model pcnbv_sph --loss squared --models 2 --epochs 100
    python scripts/fit_check.py --model pcnbv --loss listwise --dataset data/generated/research

Trains a fresh network with the steps of ``python -m train`` (its loss, weight penalty and
learning-rate schedule) on the samples of the first ``--models`` models of the train split, and
prints after every epoch the Spearman correlation of its predictions with the true gains on those
same samples: overall, at early steps (0-1) and at late steps (2 and later). A setting not given
keeps ``python -m train``'s default, but batch 8, float32 and no augmentation (as the check in
``tests/test_train.py``). Nothing is written but ``--out`` (the rows as JSON) when given.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from omegaconf import OmegaConf  # noqa: E402

from train.config import L2_SCOPES, LOSSES, ModelSettings, ScoreSettings, TrainSettings  # noqa: E402

MODELS = ("pcnbv", "pcnbv_sph", "tiny")


def model_settings(name: str) -> ModelSettings:
    """The network of ``conf/model/<name>.yaml`` (each extends ``pcnbv.yaml``)."""
    folder = ROOT / "conf" / "model"
    merged = OmegaConf.merge(
        OmegaConf.load(folder / "pcnbv.yaml"), OmegaConf.load(folder / f"{name}.yaml")
    )
    cfg = OmegaConf.to_container(merged)
    return ModelSettings(cfg["name"], cfg["input"], dict(cfg["net"]))


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", choices=MODELS, default="pcnbv_sph")
    p.add_argument("--loss", choices=LOSSES, default=None, help="default: python -m train's")
    p.add_argument("--models", type=int, default=2, help="models whose samples are trained on")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--dataset", type=Path, default=ROOT / "data" / "generated" / "synthetic")
    p.add_argument("--score", choices=("coverage", "vig"), default="coverage")
    p.add_argument("--lr", type=float, default=None, help="default: python -m train's")
    p.add_argument("--lr-decay", type=float, default=None, help="factor every --lr-step-epochs")
    p.add_argument("--lr-step-epochs", type=int, default=None)
    p.add_argument("--l2", type=float, default=None, help="default: python -m train's")
    p.add_argument("--l2-scope", choices=L2_SCOPES, default=None)
    p.add_argument("--batch-size", type=int, default=8, help="8: a few batches of a few models")
    p.add_argument("--augment", action="store_true", help="map samples by random symmetries")
    p.add_argument("--precision", default="fp32", choices=("auto", "fp32", "bf16"))
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None, help="write the rows here as JSON")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    # torch loads after the arguments are read: --help answers at once.
    import nbv.dataset
    from nbv.dataset.samples import load_samples
    from train.augment import Augmentation
    from train.fitcheck import first_models, fit_check

    # What is not given keeps python -m train's default.
    optional = ("loss", "lr", "lr_decay", "lr_step_epochs", "l2", "l2_scope")
    given = {k: getattr(args, k) for k in optional if getattr(args, k) is not None}
    settings = TrainSettings(
        dataset=args.dataset, out_dir=Path("unused"), score=ScoreSettings(args.score),
        model=model_settings(args.model), seed=args.seed, epochs=args.epochs,
        batch_size=args.batch_size, precision=args.precision, threads=args.threads,
        progress=False, augment=args.augment, **given,
    )  # fmt: skip
    samples = first_models(load_samples(args.dataset, args.score), args.models)
    augmentation = None
    if args.augment:
        viewspace = str(samples.attrs.get("viewspace", "original"))
        directions = nbv.dataset.open(args.dataset).viewspaces[viewspace]
        augmentation = Augmentation(directions, int(samples.attrs.get("lmax", 3)))
    models = ", ".join(dict.fromkeys(samples.key.tolist()))
    print(f"{settings.model.name}, loss {settings.loss}, lr {settings.lr} (x {settings.lr_decay} "
          f"every {settings.lr_step_epochs} epochs), l2 {settings.l2} ({settings.l2_scope}): "
          f"{len(samples)} samples of {models}")  # fmt: skip
    print("epoch  loss        spearman  early   late    best-view hits")
    start = time.perf_counter()
    rows = []

    def show(row: dict) -> None:
        rows.append(row)
        print(f"{row['epoch']:5d}  {row['train_loss']:10.4g}  {row['train_spearman']:8.3f}  "
              f"{row['train_spearman_early']:6.3f}  {row['train_spearman_late']:6.3f}  "
              f"{row['train_best_view_hits']:6.3f}", flush=True)  # fmt: skip

    fit_check(samples, settings, augmentation, on_epoch=show)
    print(f"{time.perf_counter() - start:.0f} s")
    if args.out:
        given = {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()}
        args.out.write_text(json.dumps({"args": given, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
