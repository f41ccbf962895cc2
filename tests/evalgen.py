"""Evaluation settings on the tiny dataset (:func:`datagen.make_tiny_dataset`)."""

from __future__ import annotations

from pathlib import Path

from nbv.eval.config import DisturbSettings, EvalSettings
from nbv.policies.method import CHECKS
from nbv.policies.registry import NETWORK_INPUTS
from nbv.setcover.settings import SetCoverSettings

#: The start views of the tiny evaluations.
STARTS = (1, 24)


def tiny_settings(
    tiny: dict[str, Path], out: Path, checks=CHECKS, disturb_start_views=(24,), **kw
) -> EvalSettings:
    """Settings of the tiny dataset written to ``out`` (the disturbance checks and their start
    views given flat, as keywords)."""
    base = dict(
        run=out.name,
        out_root=out.parent,
        data_dir=tiny["data"],
        start_views=STARTS,
        disturb=DisturbSettings(checks=checks, start_views=disturb_start_views),
        checkpoints={name: str(tiny[name]) for name in NETWORK_INPUTS},
        setcover=SetCoverSettings(n_samp=2048),
        progress=False,
    )
    base.update(kw)
    return EvalSettings(**base)
