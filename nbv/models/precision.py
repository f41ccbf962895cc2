"""Arithmetic of forward passes: float32, or bfloat16 autocast where the hardware runs it.

Forward passes may run under bfloat16 autocast (:func:`autocast`, ``"bf16"``), which CPUs with
AMX or AVX512-BF16 run 1.3-1.5x faster than float32. Only the self-attention and the wide 1x1
convs use it. The dense EdgeConv feature extractor (with its neighbour search) and the fully
connected head stay in float32 (:func:`in_float32`): neighbour ranks and the small differences
between views' predicted gains are what the output is used for, bfloat16 keeps only about three
significant digits, and the extractor's narrow products gain nothing from it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch
from torch import Tensor

from nbv.models.config import PRECISIONS


def resolve_precision(precision: str, device: torch.device | str = "cpu") -> str:
    """``"fp32"`` or ``"bf16"`` for a :data:`PRECISIONS` name on ``device``.

    ``"auto"`` is ``"bf16"`` on a CPU with AMX tiles or AVX512-BF16 instructions and on a CUDA
    device that supports bfloat16; elsewhere bfloat16 would be emulated (slower than float32),
    so it is ``"fp32"``.

    Raises:
        ValueError: an unknown name.
    """
    if precision not in PRECISIONS:
        raise ValueError(f"precision={precision!r}: must be one of {', '.join(PRECISIONS)}")
    if precision != "auto":
        return precision
    kind = torch.device(device).type
    if kind == "cuda":
        return "bf16" if torch.cuda.is_bf16_supported() else "fp32"
    if kind == "cpu" and (
        torch.cpu._is_amx_tile_supported() or torch.cpu._is_avx512_bf16_supported()
    ):
        return "bf16"
    return "fp32"


def autocast(
    precision: str, device: torch.device | str = "cpu"
) -> contextlib.AbstractContextManager:
    """The context a forward (and backward) pass runs in for ``precision`` on ``device``:
    bfloat16 autocast for ``"bf16"`` (``"auto"`` resolved by :func:`resolve_precision`),
    nothing for ``"fp32"``."""
    kind = torch.device(device).type
    enabled = resolve_precision(precision, device) == "bf16"
    return torch.autocast(kind, dtype=torch.bfloat16, enabled=enabled)


@contextlib.contextmanager
def flush_denormals() -> Iterator[None]:
    """Treat subnormal floats as zero on the CPU inside the block (FTZ/DAZ), then restore the
    state it found (so an inner block does not switch off an outer one's flushing).

    Trained weights make some activations subnormal, and x86 CPUs compute on those up to 100
    times slower: a trained PCNBV ran 3x slower than a fresh one in float32 (120 ms against
    40 ms a forward at 512 points). Values below 1e-38 change no prediction.
    """
    # torch has no getter for the flag: a subnormal times one is zero exactly when it is on.
    was_on = float(torch.tensor([1e-40]) * 1.0) == 0.0
    supported = torch.set_flush_denormal(True)
    try:
        yield
    finally:
        if supported and not was_on:
            torch.set_flush_denormal(False)


def in_float32(x: Tensor) -> contextlib.AbstractContextManager:
    """A context with autocast off on ``x``'s device (its float32 region)."""
    return torch.autocast(x.device.type, enabled=False)
