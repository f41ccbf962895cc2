"""The FLOP floor of a network episode on this machine: the float32 FLOPs of a PCNBV forward
pass, counted from its layer shapes (as written, and in the rewritten evaluation form that the
evaluator runs), over the CPU's peak float32 FLOP/s.

Peak float32 FLOP/s = cores x clock x lanes x 2 (a fused multiply-add is two FLOPs) x 2 (FMA
pipes a core). Cores are the ones this process may run on; the clock is the CPU's highest
(``cpuinfo_max_freq``, else ``cpu MHz`` of ``/proc/cpuinfo``); lanes are the float32 lanes of a
vector: 16 with AVX-512 on an Intel CPU, 8 with AVX2 and FMA (and on AMD's Zen 4, which runs
AVX-512 on two 256-bit pipes), 4 with SSE alone. Two FMA pipes is every AVX2 core's count since
Intel's Haswell and AMD's Zen 2; a CPU with one is overrated.

The clock a VM reports can be its base clock while the core runs faster: on the AVX2-only AMD
EPYC of 2026-12-04 (``cpu MHz`` 2445, no cpufreq) one thread's float32 matrix product ran
91.5 GFLOP/s, above that clock's 78 GFLOP/s "peak". So the floor divides by the higher of the
formula's peak and the rate a large matrix product reaches here on the same threads
(:func:`matmul_flops`): a floor no forward pass can beat by running faster than the formula.
Where the timed work runs partly in bfloat16 the rate is also the bfloat16 product's, when
higher (:func:`floor_rate`). A training step (forward, backward, optimizer) counts three
forwards (:func:`training_flops`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from nbv.bench.timing import best_time, torch_threads
from nbv.models.config import PCNBVConfig


def _extractor_macs(config: PCNBVConfig, n: int) -> int:
    """Multiply-adds of the feature extractor of one sample of ``n`` points (both forms)."""
    c0, g, k = config.first_channels, config.growth, config.k
    macs = n * 3 * c0  # the first 1x1 conv
    for block in range(config.blocks):
        if block:  # the squeeze 1x1 conv to c0 before every block but the first
            macs += n * (c0 + block * config.block_out_channels) * c0
        macs += n * n * c0  # the neighbour search's distance product
        macs += 2 * n * c0 * g  # the first dense layer: neighbour and centre parts, per point
        for layer in range(1, config.dense_layers):
            macs += n * k * layer * g * g + n * c0 * g  # edge part per edge, centre part per point
    return macs


def _tail_macs(config: PCNBVConfig, n: int, first: int) -> int:
    """Multiply-adds of the 1x1 convs after the first one (whose are ``first``) and the head."""
    widths = config.conv_channels
    macs = first + sum(n * p * q for p, q in zip(widths[:-1], widths[1:], strict=True))
    widths = (config.conv_channels[-1], *config.fc_channels, config.n_views)
    return macs + sum(p * q for p, q in zip(widths[:-1], widths[1:], strict=True))


def pcnbv_flops(config: PCNBVConfig, n_points: int) -> int:
    """FLOPs (2 a multiply-add) of the matrix products of one forward pass of one sample of
    :class:`~nbv.models.pcnbv.PCNBV` as written (the training form): the dense EdgeConv's split
    first layer, the neighbour search's distance products, attention, the 1x1 convs, the head.
    Element-wise work (ReLU, softmax, max, biases) is left out, a few percent at most.

    Args:
        config: the network's sizes.
        n_points: points the sample holds (``eval_points``, or ``4 (lmax+1)^2`` for a signature).
    """
    n, c, a = n_points, config.concat_channels, config.attention_channels
    macs = _extractor_macs(config, n)
    macs += 2 * n * c * a + n * c * c  # query, key, value
    macs += n * n * a + n * n * c  # q k^T, attention times values
    macs += _tail_macs(config, n, n * c * config.conv_channels[0])
    return 2 * macs


def training_flops(config: PCNBVConfig, n_points: int) -> int:
    """FLOPs of one training step of one sample: three forward passes as written
    (:func:`pcnbv_flops`), the usual estimate of a forward plus a backward that computes the
    gradients of both the weights and the activations (each twice the forward's products).
    Torch's ``FlopCounterMode`` counts 0.2-1.3 % fewer (the first conv's input and the neighbour
    search's distance products need no gradient); the optimizer's element-wise update is left
    out.

    Args:
        config: the network's sizes.
        n_points: points the sample holds.
    """
    return 3 * pcnbv_flops(config, n_points)


def inference_flops(config: PCNBVConfig, n_points: int) -> int:
    """FLOPs as :func:`pcnbv_flops` counts them, of the rewritten evaluation-mode forward of
    :class:`~nbv.models.inference.InferencePCNBV` (what evaluation and the bench run): queries
    and keys of the per-point channels only, the attention times the per-point features, one
    first conv of twice their channels, and the per-sample products of the global feature and
    the view state."""
    n, p, a = n_points, config.point_channels, config.attention_channels
    rest = p + config.n_views  # the global feature and the view state, once a sample
    macs = _extractor_macs(config, n)
    macs += 2 * n * p * a + rest * a  # queries and keys of the points; the query's constant
    macs += n * n * a + n * n * p  # q k^T, attention times the per-point features
    first = config.conv_channels[0]
    macs += _tail_macs(config, n, n * 2 * p * first + rest * first)
    return 2 * macs


@dataclass(frozen=True)
class Peak:
    """The CPU's peak float32 FLOP/s and what it is made of (:func:`peak_flops`)."""

    cores: int
    ghz: float
    lanes: int
    flops: float

    def formula(self) -> str:
        """``cores x GHz x lanes x 2 x 2 = GFLOP/s``, as the bench's note prints it."""
        return (
            f"{self.cores} core{'s' * (self.cores != 1)} x {self.ghz:.2f} GHz x {self.lanes} "
            "lanes x 2 (FMA) x 2 pipes "
            f"= {self.flops / 1e9:.0f} GFLOP/s"
        )


def peak_flops(cpuinfo: str | None = None, max_khz: int | None = None,
               cores: int | None = None) -> Peak:  # fmt: skip
    """This machine's peak float32 FLOP/s (the module docstring's formula).

    Args:
        cpuinfo: the text of ``/proc/cpuinfo``; None = read it.
        max_khz: the highest clock in kHz; None = ``/sys/.../cpuinfo_max_freq`` when readable,
            else ``cpu MHz`` of ``cpuinfo``.
        cores: cores to count; None = those this process may run on.

    Raises:
        ValueError: ``cpuinfo`` names no flags or no clock.
    """
    if cpuinfo is None:
        cpuinfo = Path("/proc/cpuinfo").read_text()
    fields: dict[str, str] = {}
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    if "flags" not in fields:
        raise ValueError("/proc/cpuinfo names no CPU flags: the peak FLOP/s is unknown")
    flags = set(fields["flags"].split())
    if max_khz is None:
        limit = Path("/sys/devices/system/cpu/cpu0/cpufreq/cpuinfo_max_freq")
        if limit.is_file():
            max_khz = int(limit.read_text())
        elif "cpu MHz" in fields:
            max_khz = int(float(fields["cpu MHz"]) * 1000)
        else:
            raise ValueError("neither cpufreq nor /proc/cpuinfo gives the clock")
    if cores is None:
        cores = len(os.sched_getaffinity(0))
    intel = fields.get("vendor_id") == "GenuineIntel"
    if "avx512f" in flags and intel:
        lanes = 16
    elif {"avx2", "fma"} <= flags:
        lanes = 8
    else:
        lanes = 4
    ghz = max_khz / 1e6
    return Peak(cores, ghz, lanes, cores * ghz * 1e9 * lanes * 2 * 2)


#: The product :func:`matmul_flops` times: (M, K) x (K, N), PCNBV's widest 1x1 conv on four
#: samples of 512 points, large enough for the BLAS to reach its peak rate.
MATMUL_SHAPE = (2048, 1024, 1024)


#: How :func:`matmul_flops` and the notes name a precision's matrix product.
PRODUCT_NAMES = {"fp32": "float32", "bf16": "bfloat16"}


def matmul_flops(threads: int | None = None, shape: tuple[int, int, int] = MATMUL_SHAPE,
                 repeat: int = 10, precision: str = "fp32") -> float:  # fmt: skip
    """The best FLOP/s of a ``torch`` matrix product of ``shape`` (M, K, N) over ``repeat``
    runs, on ``threads`` torch threads (None: the process's), after one warm-up run: the rate
    this machine's BLAS reaches, to set beside :func:`peak_flops`. ``precision``: the operands'
    type, ``"fp32"`` (float32) or ``"bf16"`` (bfloat16, cast before the timing).

    Raises:
        ValueError: a shape with a non-positive size, ``repeat`` < 1, or another precision.
    """
    import torch

    m, k, n = shape
    if min(m, k, n) < 1 or repeat < 1:
        raise ValueError(f"shape {shape} needs positive sizes and repeat={repeat} >= 1")
    if precision not in PRODUCT_NAMES:
        raise ValueError(f"precision={precision!r}: must be one of {', '.join(PRODUCT_NAMES)}")
    dtype = torch.bfloat16 if precision == "bf16" else torch.float32
    generator = torch.Generator().manual_seed(0)
    a = torch.rand(m, k, generator=generator).to(dtype)
    w = torch.rand(n, k, generator=generator).to(dtype)
    with torch_threads(threads):
        torch.nn.functional.linear(a, w)  # warm-up: it allocates and picks kernels
        best = best_time(lambda: torch.nn.functional.linear(a, w), repeat, float("inf"))
    return 2.0 * m * k * n / best


@dataclass(frozen=True)
class FloorRate:
    """The FLOP/s a row's floor divides by (:func:`floor_rate`).

    Attributes:
        peak: the clock formula's peak on the row's threads.
        matmul: the measured FLOP/s of a matrix product of ``shape`` by precision (``"fp32"``,
            and ``"bf16"`` where the timed work runs partly in bfloat16).
        shape: the product's (M, K, N).
    """

    peak: Peak
    matmul: dict[str, float]
    shape: tuple[int, int, int] = MATMUL_SHAPE

    @property
    def flops(self) -> float:
        """The highest of the peak and the measured rates, FLOP/s."""
        return max(self.peak.flops, *self.matmul.values())

    def describe(self) -> str:
        """``R GFLOP/s, the higher of (formula) and the M GFLOP/s of a ... matrix product here``,
        as the rows' notes print it."""
        shape = "x".join(map(str, self.shape))
        products = " and the ".join(
            f"{rate / 1e9:.0f} GFLOP/s of a {shape} {PRODUCT_NAMES[p]} matrix product"
            for p, rate in self.matmul.items()
        )
        return (
            f"{self.flops / 1e9:.0f} GFLOP/s, the higher of ({self.peak.formula()}) and the "
            f"{products} here"
        )


def floor_rate(threads: int | None = None, precision: str = "fp32",
               shape: tuple[int, int, int] = MATMUL_SHAPE) -> FloorRate:  # fmt: skip
    """The floor's rate on ``threads`` torch threads (None: the process's; the clock formula
    counts as many cores): the clock formula's peak, or what a float32 matrix product of
    ``shape`` reaches here when the core runs faster than the clock the machine reports, and
    for ``precision="bf16"`` (work partly under bfloat16 autocast) a bfloat16 product's too."""
    matmul = {"fp32": matmul_flops(threads, shape)}
    if precision == "bf16":
        matmul["bf16"] = matmul_flops(threads, shape, precision="bf16")
    return FloorRate(peak_flops(cores=threads), matmul, shape)
