"""Small networks for tests, saved the way training saves them."""

from __future__ import annotations

from pathlib import Path

#: A very small PCNBV (the same sizes as conf/model/tiny.yaml).
TINY_NET = dict(
    k=4, growth=4, dense_layers=2, blocks=2, first_channels=8, attention_channels=8,
    conv_channels=[32], fc_channels=[32],
)  # fmt: skip


def save_tiny_checkpoint(
    path: Path, input: str = "points", seed: int = 0, selection_keys: list[str] | None = None
) -> Path:
    """An untrained tiny PCNBV saved the way training saves one (``extra``: input, lmax,
    eval_points, and the models that chose it); ``input="directions"``: a tiny
    viewspace-conditioned network the way train.conditioned saves one (``"directions_map"``:
    one that reads map features)."""
    import torch

    from nbv.infogain.view_features import FEATURES
    from nbv.models.checkpoints import save_checkpoint
    from nbv.models.config import PCNBVConfig
    from nbv.models.pcnbv import PCNBV
    from nbv.models.view_conditioned import ConditionedConfig, ViewConditionedNet, save_conditioned

    torch.manual_seed(seed)
    if input.startswith("directions"):
        width = len(FEATURES) if input == "directions_map" else 0
        config = ConditionedConfig((8, 16), (8,), 4, (16,), map_features=width)
        extra = {"eval_points": 64, "selection_keys": selection_keys or []}
        save_conditioned(path, ViewConditionedNet(config).eval(), extra)
        return path
    net = PCNBV(PCNBVConfig(n_views=33, **TINY_NET)).eval()
    extra = {"input": input, "lmax": 2, "eval_points": 64, "selection_keys": selection_keys or []}
    save_checkpoint(path, net, extra)
    return path
