"""Torch's CPU threads on a machine that other processes share (no torch import here).

The pip build of torch runs its intra-op pool on GNU libgomp (``torch.__config__.parallel_info()``:
"ATen parallel backend: OpenMP"; ``torch/lib/libgomp.so.1``), so Intel's ``KMP_BLOCKTIME`` does
nothing. libgomp's idle threads spin (300,000 rounds by default) before they sleep. Beside another
CPU-bound process, the pool's thread on the shared core spins away its share of that core, then
waits for a time slice at every one of a forward pass's few hundred parallel regions: a 9-view
PCNBV episode ran 3.9x and a PCNBV-sph episode 11x slower beside a busy loop (2 cores, 2 torch
threads, issue 31). A thread that sleeps instead is woken promptly (the scheduler favours a
thread that has slept): with ``OMP_WAIT_POLICY=PASSIVE`` the same episodes ran 1.1x and 1.9x
slower. libgomp reads its settings once, when torch loads it: :func:`configure_openmp` must run
before ``import torch``.
"""

from __future__ import annotations

import logging
import os
import sys

log = logging.getLogger(__name__)

#: The environment :func:`configure_openmp` sets where the user has not: threads that sleep
#: when idle (libgomp's spin count is then 0).
OPENMP_DEFAULTS = {"OMP_WAIT_POLICY": "PASSIVE"}


def configure_openmp() -> bool:
    """Set :data:`OPENMP_DEFAULTS` in the environment (a value the user set wins), before torch
    is imported; entry points call it first.

    Returns:
        True when torch was not loaded yet (the settings take effect); False, with a logged
        warning, when it was (they do not, for this process; spawned workers still get them).
    """
    for key, value in OPENMP_DEFAULTS.items():
        os.environ.setdefault(key, value)
    if "torch" in sys.modules:
        log.warning(
            "torch was imported before configure_openmp(): its OpenMP threads keep their "
            "spinning wait in this process (set OMP_WAIT_POLICY=PASSIVE before it starts)"
        )
        return False
    return True
