"""The one declaration of the networks the toolkit trains: :data:`NETWORKS`.

Each :class:`Network` names its sizes' dataclass and its ``torch.nn.Module`` (as import paths,
``"module:attribute"``, so that the settings that name a network are checked without torch), and
the command that trains it. A trainer builds its network through :func:`fresh_network` and a
checkpoint reader through :func:`network_class`, so a new network is one row here and its
module (docs/development.md, "Adding a network").
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from nbv.utils.declared import look_up

#: The trainers: ``python -m <trainer>``. ``train`` trains a network that scores every view of
#: a viewspace from a cloud and the view state (``forward(cloud, view_state) -> (B, V)``).
TRAINERS = ("train", "train.conditioned", "train.completion")


@dataclass(frozen=True)
class Network:
    """One network.

    A network of ``python -m train`` (trainer ``train``) has a config with ``n_views`` (one
    output per view), ``to_dict()`` and ``from_dict(dict)`` (its checkpoints store it), and
    ``forward(points (B, N, 3), view_state (B, V)) -> (B, V)`` scores; its checkpoints record
    its name, and :func:`nbv.models.checkpoints.load_checkpoint` builds it by that name.

    Attributes:
        name: its name (``model.network`` of ``python -m train``).
        summary: one line: what it reads and what it outputs.
        config: ``"module:Class"`` of its sizes, a frozen dataclass whose fields are the
            trainer's ``net`` keys (``n_views``, where it has one, comes from the dataset).
        model: ``"module:Class"`` of its ``torch.nn.Module``, built from a config.
        trainer: the command that trains it (:data:`TRAINERS`).
    """

    name: str
    summary: str
    config: str
    model: str
    trainer: str

    def __post_init__(self) -> None:
        if self.trainer not in TRAINERS:
            raise ValueError(f"network {self.name}: trainer={self.trainer!r}; allowed: {TRAINERS}")


#: Every network, by name.
NETWORKS: dict[str, Network] = {
    n.name: n
    for n in (
        Network(
            "pcnbv",
            "PC-NBV: a cloud (points or a spherical signature) and the view state -> a score per "
            "view",
            "nbv.models.config:PCNBVConfig",
            "nbv.models.pcnbv:PCNBV",
            "train",
        ),
        Network(
            "vcnbv",
            "the viewspace-conditioned network: a cloud, the candidates' directions (and map "
            "features) -> a score per candidate",
            "nbv.models.view_conditioned:ConditionedConfig",
            "nbv.models.view_conditioned:ViewConditionedNet",
            "train.conditioned",
        ),
        Network(
            "completion",
            "the completion network: a captured cloud -> points on the whole surface",
            "nbv.models.completion:CompletionConfig",
            "nbv.models.completion:CompletionNet",
            "train.completion",
        ),
    )
}


def network(name: str) -> Network:
    """The declared network ``name``.

    Raises:
        ValueError: no such network (the message lists the declared ones).
    """
    return look_up(NETWORKS, name, "network", "declared")


def _attribute(path: str) -> Any:
    module, _, attribute = path.partition(":")
    return getattr(importlib.import_module(module), attribute)


def network_config_class(name: str) -> type:
    """The sizes' dataclass of network ``name``."""
    return _attribute(network(name).config)


def network_config(name: str, **sizes: Any) -> Any:
    """The sizes' dataclass of network ``name`` with ``sizes`` (the others its defaults)."""
    return network_config_class(name)(**sizes)


def network_class(name: str) -> type:
    """The ``torch.nn.Module`` class of network ``name``."""
    return _attribute(network(name).model)


def fresh_network(name: str, config: Any = None, **sizes: Any) -> Any:
    """A fresh network ``name`` (weights from torch's generator: seed it first) of ``config``,
    else of :func:`network_config` of ``sizes``."""
    return network_class(name)(config if config is not None else network_config(name, **sizes))
