"""The held-out category, scored once, with the chosen checkpoint only.

The fold's network (``best.pt``, chosen without the held-out category) plays an episode from every
start view on every model of the held-out category; the registry's baselines (:data:`BASELINES`:
random, averaged over ``repeats`` seeds per episode, spread and the coverage oracle) play the same
episodes. ``heldout.json`` keeps every episode's AUC and coverage curve, so :mod:`train.summary`
can pair the methods episode by episode.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
from tqdm import tqdm

from nbv.models.checkpoints import load_checkpoint
from nbv.policies.episode import EPISODE_VIEWS, run_episode
from nbv.policies.method import MethodContext
from nbv.policies.network import NetworkPolicy
from nbv.policies.registry import BASELINES, METHODS
from nbv.setcover.settings import SetCoverSettings
from nbv.utils.atomic import write_text
from nbv.utils.seeding import named_rng
from train.config import TrainSettings

log = logging.getLogger(__name__)

#: The file in the run folder.
HELDOUT_FILE = "heldout.json"
#: The methods it holds, the fold's network (``network``) first.
HELDOUT_METHODS = ("network", *BASELINES)
#: The baseline whose seeds ``random_repeats`` counts (a stochastic one: its policy is random).
_STOCHASTIC = tuple(name for name in BASELINES if METHODS[name].stochastic)


def score_heldout(
    dataset, keys: list[str], start_views, network, seed: int, repeats: int, progress: bool
) -> dict:
    """Episodes of the network and the baselines on the held-out models, original viewspace.

    Args:
        dataset: the opened dataset.
        keys: the held-out category's models.
        start_views: the episodes' start views.
        network: a :class:`nbv.policies.network.NetworkPolicy` of the chosen checkpoint.
        seed: the run's seed (random's generators derive from it, the key, the start, the repeat).
        repeats: random's seeds per episode (its AUC and curve are their means).
        progress: show a progress bar.

    Returns:
        ``episodes`` ([key, start] pairs), ``categories``, ``auc`` (method -> per-episode AUC),
        ``coverage`` (method -> per-episode curves) and ``random_repeats``.
    """
    out: dict = {
        "episodes": [], "categories": [], "random_repeats": int(repeats),
        "auc": {m: [] for m in HELDOUT_METHODS}, "coverage": {m: [] for m in HELDOUT_METHODS},
    }  # fmt: skip

    def record(method: str, episodes: list) -> None:
        out["auc"][method].append(float(np.mean([e.auc for e in episodes])))
        out["coverage"][method].append(np.mean([e.coverage for e in episodes], axis=0).tolist())

    # The baselines read none of the context but the camera: no network, no planner.
    context = MethodContext({}, SetCoverSettings(), dataset.intrinsics,
                            float(dataset.attrs["eps"]), EPISODE_VIEWS)  # fmt: skip
    bar = tqdm(total=len(keys) * len(start_views), desc="held-out episodes", disable=not progress)
    for key in keys:
        model = dataset.model(key, ("original",))
        for start in start_views:
            start = int(start)
            out["episodes"].append([key, start])
            out["categories"].append(model.category)
            record("network", [run_episode(model, "original", start, network.fresh())])
            for name in BASELINES:
                # A stochastic baseline's seeds are named by its episode and repeat (the names
                # runs made before this loop used: "heldout-random").
                rngs = [named_rng(seed, f"heldout-{name}", key, start, r)
                        for r in range(repeats if name in _STOCHASTIC else 1)]  # fmt: skip
                build = METHODS[name].build
                record(name, [run_episode(model, "original", start, build(context, rng))
                              for rng in rngs])  # fmt: skip
            bar.update()
    bar.close()
    return out


def heldout_result(out_dir: Path, dataset, keys: list[str], settings: TrainSettings, n_views: int):
    """``heldout.json`` of ``best.pt``: read back when it belongs to this best.pt, else scored."""
    best = out_dir / "best.pt"
    _, extra = load_checkpoint(best, n_views=n_views)
    stamp = {"epoch": int(extra["epoch"]), "select": settings.select,
             "random_repeats": settings.random_repeats}  # fmt: skip
    path = out_dir / HELDOUT_FILE
    if path.exists():
        saved = json.loads(path.read_text())
        if saved.get("checkpoint") == stamp and saved.get("start_views") == list(
            settings.start_views
        ):
            return saved
    log.info("scoring best.pt (epoch %d) on the held-out category %s (%d models)",
             stamp["epoch"] + 1, settings.held_out, len(keys))  # fmt: skip
    result = score_heldout(
        dataset, keys, settings.start_views, NetworkPolicy.from_checkpoint(best, n_views=n_views),
        settings.seed, settings.random_repeats, settings.progress,
    )  # fmt: skip
    result.update(
        checkpoint=stamp,
        start_views=list(settings.start_views),
        held_out=settings.held_out,
        selection_keys=extra.get("selection_keys"),
    )
    write_text(path, json.dumps(result, indent=1))
    return result
