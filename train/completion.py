"""Training of the completion network (:mod:`nbv.models.completion`).

``python -m train.completion [key=value ...]`` (``conf/train_completion.yaml``).

1. **Data.** The shards of :mod:`train.completion_data` in ``data_dir``: the training categories'
   synthetic models ray cast from the original and permuted viewspaces and from random
   directions. Missing shards are made first (resumable: a killed run keeps the finished ones).
   The 8 unseen categories are never made.
2. **Fit.** Each epoch draws ``samples_per_epoch`` inputs (a seeded generator per epoch): a
   training model, a view group, 1 to 5 of its views, their points farthest-point sampled to the
   network's input. The loss is CD-L1 on the coarse cloud plus ``alpha`` times CD-L1 on the fine
   one, both against the stored true surface; ``alpha`` rises as PCN's does
   (:func:`fine_weight`, by epoch). Adam, the learning rate times ``lr_decay`` every
   ``lr_step_epochs`` epochs, bfloat16 autocast where the CPU runs it natively (``precision``).
3. **Choice.** After every epoch the fine cloud's CD-L1 on fixed samples of the valid split
   (``val_per_model`` a model) is measured; ``best.pt`` is the epoch of the lowest. ``last.pt``
   (weights, optimizer, epoch) is written every epoch, and a rerun with the same settings
   resumes from it; with other settings it refuses, naming the keys that differ.
   ``metrics.csv`` holds a row per epoch and ``curve.png`` draws it.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from nbv.config.cli import command
from nbv.config.schema import ConfigError, PathsConfig
from nbv.config.settings import Entry, check_ranges, setting
from nbv.models.checkpoints import CheckpointError
from nbv.models.completion import (
    CompletionConfig,
    CompletionNet,
    chamfer_l1,
    completion_flops,
    parameter_count,
)
from nbv.models.completion_inference import save_completion
from nbv.models.networks import fresh_network
from nbv.models.precision import autocast, resolve_precision
from nbv.utils.atomic import atomic_path, write_text
from nbv.utils.fields import at_least, between, one_of, positive
from nbv.utils.seeding import named_rng
from train import completion_data as cdata
from train.run_log import append_csv_rows

log = logging.getLogger("train.completion")
PROG = "train.completion"
#: Settings that may differ when a run resumes: they do not change its numbers.
RESUMABLE = ("epochs", "progress", "threads", "out_dir", "data_dir")


@dataclass(frozen=True)
class CompletionSettings:
    """Training of the completion network (``python -m train.completion``).

    Attributes:
        data_dir: the completion data's shards (made there when missing).
        out_dir: where ``best.pt``, ``last.pt``, ``metrics.csv``, ``settings.json`` and
            ``curve.png`` go.
        seed: seeds the data's draws, the initialisation and every epoch's samples.
        train_models: models of each training category's train split.
        valid_models: models of each training category's valid split.
        n_random: random view directions per model, beside the two viewspaces' 66.
        points_per_view: points kept of each rendered view.
        n_gt: points of the true surface the loss compares with.
        shards: shards of the data.
        n_input: points of the network's input cloud.
        n_coarse: points of the coarse cloud.
        fold: side of the folding grid (``n_coarse * fold ** 2`` output points).
        epochs: training epochs.
        samples_per_epoch: input clouds drawn per epoch.
        batch_size: clouds per step.
        lr: Adam's learning rate.
        lr_decay: the learning rate's factor every ``lr_step_epochs`` epochs.
        lr_step_epochs: see ``lr_decay``.
        val_per_model: fixed validation samples of each valid model.
        precision: ``auto`` (bfloat16 where the CPU runs it natively), ``fp32`` or ``bf16``.
        threads: torch threads; 0 = torch's default.
        progress: show progress bars.
    """

    data_dir: Path
    out_dir: Path
    seed: int = 0
    train_models: int = setting(125, allows=at_least(1))
    valid_models: int = setting(4, allows=at_least(1))
    n_random: int = setting(16, allows=at_least(0))
    points_per_view: int = setting(512, allows=at_least(16))
    n_gt: int = setting(2048, allows=at_least(64))
    shards: int = setting(8, allows=at_least(1))
    n_input: int = setting(512, allows=at_least(16))
    n_coarse: int = setting(512, allows=at_least(16))
    fold: int = setting(2, allows=at_least(1))
    epochs: int = setting(60, allows=at_least(1))
    samples_per_epoch: int = setting(4000, allows=at_least(1))
    batch_size: int = setting(32, allows=at_least(1))
    lr: float = setting(1e-3, allows=positive())
    lr_decay: float = setting(0.7, allows=between(0, 1, "(]"))
    lr_step_epochs: int = setting(10, allows=at_least(1))
    val_per_model: int = setting(4, allows=at_least(1))
    precision: str = setting("auto", allows=one_of(("auto", "fp32", "bf16")))
    threads: int = setting(0, allows=at_least(0))
    progress: bool = True

    def __post_init__(self) -> None:
        check_ranges(self)

    @property
    def data(self) -> cdata.DataSettings:
        """How the data is made."""
        return cdata.DataSettings(
            self.train_models, self.valid_models, self.n_random, self.points_per_view,
            self.n_gt, self.seed, self.shards,
        )  # fmt: skip

    def model_config(self) -> CompletionConfig:
        """The network's shape."""
        return CompletionConfig(n_input=self.n_input, n_coarse=self.n_coarse, fold=self.fold)

    def identity(self) -> dict:
        """The settings that change the run's numbers (JSON types)."""
        out = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(self).items()}
        return {k: v for k, v in out.items() if k not in RESUMABLE}


ENTRY = Entry("train_completion_schema", CompletionSettings, extra=(("paths", PathsConfig),))


def fine_weight(epoch: int) -> float:
    """The fine cloud's weight ``alpha`` in epoch ``epoch`` (0-based): PCN's schedule (0.01,
    0.1, 0.5, 1.0 from 0, 3 %, 7 % and 17 % of its 300k steps) over the default 60 epochs,
    fixed by epoch so that ``epochs`` changes no epoch's numbers (a run may train on)."""
    return 0.01 if epoch < 2 else 0.1 if epoch < 5 else 0.5 if epoch < 11 else 1.0


def _batch(data: cdata.CompletionData, models: np.ndarray, rng: np.random.Generator,
           n_input: int) -> tuple[torch.Tensor, torch.Tensor]:  # fmt: skip
    clouds = [cdata.draw_sample(data, int(m), rng, n_input)[0] for m in models]
    gts = data.gt[models].astype(np.float32)
    return torch.from_numpy(np.stack(clouds)), torch.from_numpy(gts)


def validate(
    model: CompletionNet, data: cdata.CompletionData, valid: list, precision: str, batch: int
) -> dict[str, float]:
    """Mean CD-L1 of the coarse and fine clouds on the fixed validation samples ``valid``
    (``(model, input, views)`` tuples), and the fine one's by number of views."""
    model.eval()
    coarse_cd, fine_cd, views = [], [], []
    with torch.no_grad():
        for start in range(0, len(valid), batch):
            part = valid[start : start + batch]
            x = torch.from_numpy(np.stack([p[1] for p in part]))
            gt = torch.from_numpy(data.gt[[p[0] for p in part]].astype(np.float32))
            with autocast(precision):
                coarse, fine = model(x)
            coarse_cd.append(chamfer_l1(coarse, gt).numpy())
            fine_cd.append(chamfer_l1(fine, gt).numpy())
            views.extend(p[2] for p in part)
    fine_all, views_all = np.concatenate(fine_cd), np.array(views)
    row = {"val_cd_coarse": float(np.concatenate(coarse_cd).mean()),
           "val_cd_fine": float(fine_all.mean())}  # fmt: skip
    for k in range(1, 6):
        row[f"val_cd_fine_{k}v"] = (
            float(fine_all[views_all == k].mean()) if (views_all == k).any() else float("nan")
        )
    return row


def _resume(out_dir: Path, identity: dict, model, optimizer) -> tuple[int, float]:
    """The epochs done and the best validation CD-L1 of a run in ``out_dir`` (0, inf: none).

    Raises:
        ConfigError: the run there was made with other settings (the keys are named).
    """
    last = out_dir / "last.pt"
    if not last.exists():
        return 0, float("inf")
    try:
        state = torch.load(last, map_location="cpu", weights_only=True)
        saved = json.loads(state["identity"])
    except Exception as err:  # a torn or foreign file: say which, never a traceback
        raise CheckpointError(f"{last}: not a completion run's last.pt ({err})") from err
    changed = sorted(k for k in set(saved) | set(identity) if saved.get(k) != identity.get(k))
    if changed:
        raise ConfigError(
            f"{out_dir} holds a run with other settings ({', '.join(changed)}): give another "
            "out_dir, or delete that folder"
        )
    model.load_state_dict(state["model"])
    optimizer.load_state_dict(state["optimizer"])
    return int(state["epoch"]), float(state["best"])


def _save_last(out_dir: Path, identity: dict, model, optimizer, epoch: int, best: float) -> None:
    state = {"identity": json.dumps(identity, sort_keys=True), "model": model.state_dict(),
             "optimizer": optimizer.state_dict(), "epoch": epoch, "best": best}  # fmt: skip
    with atomic_path(out_dir / "last.pt") as tmp, open(tmp, "wb") as f:
        torch.save(state, f)


def draw_curve(metrics: Path, out: Path) -> None:
    """``curve.png``: training loss and validation CD-L1 by epoch, from ``metrics.csv``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = np.genfromtxt(metrics, delimiter=",", names=True)
    rows = np.atleast_1d(rows)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(rows["epoch"], rows["val_cd_fine"], label="validation CD-L1, fine")
    ax.plot(rows["epoch"], rows["val_cd_coarse"], label="validation CD-L1, coarse", ls="--")
    ax.plot(rows["epoch"], rows["train_cd_fine"], label="training CD-L1, fine", ls=":")
    ax.set_xlabel("epoch")
    ax.set_ylabel("CD-L1 (normalised frame, radius 0.5)")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def run(settings: CompletionSettings) -> dict:
    """Make the missing data, then train (or resume); return the best epoch's metrics row."""
    if settings.threads:
        torch.set_num_threads(settings.threads)
    torch.manual_seed(settings.seed)
    out_dir = settings.out_dir
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = cdata.make_shards(settings.data_dir, settings.data, settings.progress)
    data = cdata.load(paths, settings.data)
    train_idx, valid_idx = data.subset("train"), data.subset("valid")
    if len(train_idx) == 0 or len(valid_idx) == 0:
        raise ConfigError(f"{settings.data_dir}: no training or no validation models")
    config = settings.model_config()
    model = fresh_network("completion", config)
    optimizer = torch.optim.Adam(model.parameters(), lr=settings.lr)
    identity = settings.identity()
    done, best = _resume(out_dir, identity, model, optimizer)
    write_text(out_dir / "settings.json", json.dumps(identity, indent=1, sort_keys=True))
    precision = resolve_precision(settings.precision)
    valid = list(cdata.fixed_samples(data, valid_idx, settings.seed, settings.n_input,
                                     settings.val_per_model))  # fmt: skip
    log.info("completion network: %d parameters, %.3f GFLOP a forward pass; %d training and %d "
             "validation models; %s", parameter_count(model), completion_flops(config) / 1e9,
             len(train_idx), len(valid_idx), precision)  # fmt: skip
    steps = -(-settings.samples_per_epoch // settings.batch_size)
    best_row: dict = {}
    for epoch in range(done, settings.epochs):
        lr = settings.lr * settings.lr_decay ** (epoch // settings.lr_step_epochs)
        for group in optimizer.param_groups:
            group["lr"] = lr
        alpha = fine_weight(epoch)
        rng = named_rng(settings.seed, "completion-epoch", epoch)
        model.train()
        t0, losses, fine_cds = time.perf_counter(), [], []
        bar = tqdm(range(steps), desc=f"epoch {epoch + 1}/{settings.epochs}", unit="step",
                   disable=not settings.progress)  # fmt: skip
        for _ in bar:
            picks = rng.choice(train_idx, settings.batch_size)
            x, gt = _batch(data, picks, rng, settings.n_input)
            with autocast(precision):
                coarse, fine = model(x)
            fine_cd = chamfer_l1(fine, gt).mean()
            loss = chamfer_l1(coarse, gt).mean() + alpha * fine_cd
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
            fine_cds.append(fine_cd.item())
            bar.set_postfix(cd=f"{np.mean(fine_cds[-20:]):.4f}")
        seconds = time.perf_counter() - t0
        row = {"epoch": epoch + 1, "lr": lr, "alpha": alpha, "train_loss": float(np.mean(losses)),
               "train_cd_fine": float(np.mean(fine_cds)),
               **validate(model, data, valid, precision, settings.batch_size),
               "seconds": seconds,
               "samples_per_s": steps * settings.batch_size / seconds}  # fmt: skip
        if row["val_cd_fine"] < best:
            best = row["val_cd_fine"]
            extra = {"settings": identity, "epoch": epoch + 1, "val_cd_fine": best,
                     "convention": "CD-L1",
                     "categories": [str(c) for c in np.unique(data.category)]}  # fmt: skip
            save_completion(out_dir / "best.pt", model, extra)
            best_row = row
        append_csv_rows(out_dir / "metrics.csv", [row])
        _save_last(out_dir, identity, model, optimizer, epoch + 1, best)
        log.info("epoch %d: %s", epoch + 1, {k: round(v, 5) for k, v in row.items()})
        draw_curve(out_dir / "metrics.csv", out_dir / "curve.png")
    return best_row or {"val_cd_fine": best}


def _start(cfg) -> tuple[CompletionSettings, dict]:
    from nbv.utils.lock import one_writer

    settings = ENTRY.build(cfg)
    with one_writer(settings.out_dir, "completion training run folder"):
        return settings, run(settings)


def _finish(started: tuple[CompletionSettings, dict]) -> None:
    settings, best = started
    log.info("done: best validation CD-L1 (fine) %.5f; %s", best["val_cd_fine"],
             settings.out_dir / "best.pt")  # fmt: skip


main = command(PROG, "train_completion", _start, _finish)

if __name__ == "__main__":
    main()
