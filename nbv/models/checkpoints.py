"""PCNBV checkpoints: weights, model config and extra metadata in one torch file."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch
from torch import Tensor

from nbv.models.networks import network_class, network_config_class
from nbv.models.pcnbv import PCNBV
from nbv.utils.atomic import atomic_path

#: Written into every checkpoint so that foreign files are recognised. A file-format tag, not a
#: module path: it keeps the value checkpoints were first written with, so they stay readable.
CHECKPOINT_FORMAT = "nbv.net.PCNBV"
#: Bumped when the checkpoint layout changes incompatibly.
CHECKPOINT_VERSION = 1


class CheckpointError(ValueError):
    """A checkpoint file is missing, unreadable, or does not fit the network it should hold."""


def check_plain(value: Any, where: str) -> None:
    """Raise ``TypeError`` unless ``value`` is built of types that ``torch.load`` with
    ``weights_only=True`` reads back: dict with str keys, list, tuple, str, int, float, bool,
    None, tensors."""
    if isinstance(value, Mapping):
        for key, item in value.items():
            if not isinstance(key, str):
                raise TypeError(f"checkpoint extra{where}: keys must be str, got {key!r}")
            check_plain(item, f"{where}[{key!r}]")
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            check_plain(item, f"{where}[{i}]")
    elif not (value is None or isinstance(value, str | int | float | bool | Tensor)):
        raise TypeError(
            f"checkpoint extra{where} is a {type(value).__name__}; allowed: dict, list, tuple, "
            "str, int, float, bool, None, torch.Tensor (convert numpy values and paths first)"
        )


def write_payload(
    path: str | os.PathLike[str], tag: str, version: int, model: Any, extra: Mapping[str, Any]
) -> None:
    """Write a network checkpoint atomically: the format ``tag`` and ``version``, the model's
    ``config.to_dict()``, its weights on the CPU and ``extra`` (checked by :func:`check_plain`).
    Creates missing parent folders."""
    check_plain(dict(extra), "")
    payload = {
        "format": tag,
        "version": version,
        "config": model.config.to_dict(),
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "extra": dict(extra),
    }
    # Through a file object, so that the archive's inner folder is "archive" as before, not
    # named after the temporary file: the bytes do not depend on the file name.
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        torch.save(payload, f)


def read_payload(
    path: Path, tag: str, version: int, kind: str, map_location: str | torch.device = "cpu"
) -> dict[str, Any]:
    """The payload of a checkpoint of :func:`write_payload` with format ``tag`` and ``version``.

    Raises:
        CheckpointError: (naming the file, ``kind`` naming the network) it is missing, not a
            torch file, of another format or version, or lacks its config, weights or extra.
    """
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist or is not a file")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as e:
        raise CheckpointError(f"checkpoint {path} is not a readable torch file: {e}") from e
    found = payload.get("format") if isinstance(payload, dict) else None
    if found != tag:
        which = "no format tag" if found is None else f"format tag {found!r}"
        raise CheckpointError(f"checkpoint {path} is not a {kind} checkpoint ({which})")
    if payload.get("version") != version:
        raise CheckpointError(
            f"checkpoint {path} has version {payload.get('version')!r}; "
            f"this code reads version {version}"
        )
    missing = [k for k in ("config", "state_dict", "extra") if not isinstance(payload.get(k), dict)]
    if missing:
        raise CheckpointError(f"checkpoint {path} lacks the dicts {missing}")
    bad = [name for name, value in payload["state_dict"].items()
           if not isinstance(value, Tensor)
           or (value.is_floating_point() and not bool(torch.isfinite(value).all()))]  # fmt: skip
    if bad:
        raise CheckpointError(f"checkpoint {path}: weights {bad[:3]} are not finite tensors")
    return payload


def save_checkpoint(path: str | os.PathLike[str], model: PCNBV, extra: Mapping[str, Any]) -> None:
    """Write the weights, the model config and ``extra`` (training config, dataset identity,
    epoch, metrics, ...) to ``path`` atomically: a temporary file in the same folder, renamed
    over ``path`` once complete. Creates missing parent folders.

    Raises:
        TypeError: ``extra`` holds a value :func:`load_checkpoint` could not read back safely.
    """
    write_payload(path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, model, extra)


def load_checkpoint(
    path: str | os.PathLike[str],
    map_location: str | torch.device = "cpu",
    n_views: int | None = None,
) -> tuple[PCNBV, dict[str, Any]]:
    """Read a checkpoint written by :func:`save_checkpoint`.

    Args:
        path: the checkpoint file.
        map_location: device of the returned model.
        n_views: if given, the number of views the network must have.

    Returns:
        ``(model, extra)``: the network in eval mode, and the ``extra`` dict it was saved with.

    Raises:
        CheckpointError: (naming the file) it is missing, not a torch file, not a PCNBV
            checkpoint, its config is invalid, its weights do not fit its config, or its
            number of views differs from ``n_views``.
    """
    path = Path(path)
    payload = read_payload(path, CHECKPOINT_FORMAT, CHECKPOINT_VERSION, "PCNBV", map_location)
    # A network other than PCNBV (nbv.models.networks) records its name; PCNBV's never did.
    name = payload["extra"].get("network", "pcnbv") if isinstance(payload["extra"], dict) else ""
    try:
        config = network_config_class(name).from_dict(payload["config"])
    except (TypeError, ValueError) as e:
        raise CheckpointError(f"checkpoint {path} has an invalid config: {e}") from e
    if n_views is not None and config.n_views != n_views:
        raise CheckpointError(
            f"checkpoint {path} is a network for {config.n_views} views, expected {n_views}"
        )
    model = network_class(name)(config)
    try:
        model.load_state_dict(payload["state_dict"], strict=True)
    except (RuntimeError, TypeError, AttributeError) as e:
        reason = " ".join(str(e).split())  # torch's message spans lines
        raise CheckpointError(f"checkpoint {path} weights do not fit its config: {reason}") from e
    return model.to(map_location).eval(), dict(payload["extra"])
