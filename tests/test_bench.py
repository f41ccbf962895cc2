"""The benchmark's plain reference implementations agree with the fast paths they time."""

import numpy as np
import pytest

from nbv.bench.suite import format_table, numpy_fps, python_greedy, scipy_signature
from nbv.geometry.clouds import farthest_points
from nbv.geometry.sph import signature
from nbv.setcover.greedy import greedy_max_coverage


def test_numpy_fps_equals_fpsample():
    points = np.random.default_rng(0).random((3000, 3)).astype(np.float32)
    fast = farthest_points(points, 64)
    # fpsample starts from a point of its own kd-tree order; start the reference there too.
    start = int(np.flatnonzero((points == fast[0]).all(axis=1))[0])
    np.testing.assert_array_equal(numpy_fps(points, 64, start), fast)


def test_scipy_signature_equals_recurrence_signature():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(5000, 3))
    points = d / np.linalg.norm(d, axis=1, keepdims=True) * (0.4 + 0.05 * d[:, :1] ** 2)
    np.testing.assert_allclose(scipy_signature(points, 3), signature(points, 3), atol=1e-5)


def test_python_greedy_equals_packed_greedy():
    sets = np.random.default_rng(2).random((12, 300)) < 0.2
    views, _ = greedy_max_coverage(sets, 5, (3,))
    assert python_greedy(sets, 5, (3,)) == views


def test_table_marks_missed_targets():
    rows = [
        dict(name="a", ours=0.002, reference=0.2, ratio=100.0, target=0.001, note="x"),
        dict(name="b", ours=0.0005, reference=0.2, ratio=400.0, target=0.001, note="y"),
    ]
    table = format_table(rows)
    assert "| a | 2.000 | 200.0 | 100.0x | 1 | NO | x |" in table
    assert "| b | 0.500 | 200.0 | 400.0x | 1 | yes | y |" in table
    with pytest.raises(KeyError):
        format_table([{"name": "c"}])


def test_network_episode_feeds_the_captured_views_and_refuses_revisits():
    from nbv.bench.network import network_episode

    views = [np.full((i + 1, 3), i, dtype=np.float32) for i in range(12)]
    seen = []

    def lowest_unvisited(cloud, state):
        seen.append((len(cloud), int(state.sum())))
        return int(np.flatnonzero(~state)[0])

    assert network_episode(lowest_unvisited, views, start=4) == [4, 0, 1, 2, 3, 5, 6, 7, 8, 9]
    # The cloud holds exactly the captured views' points: 5, then 5 + 1, then 5 + 1 + 2, ...
    assert seen[:3] == [(5, 1), (6, 2), (8, 3)] and len(seen) == 9
    with pytest.raises(ValueError, match="visited view 4"):
        network_episode(lambda cloud, state: 4, views, start=4)


@pytest.mark.parametrize("kind", ["points", "signature"])
def test_plain_reference_decides_like_the_policy_on_an_fp32_inference_copy(kind):
    import torch

    from nbv.bench.network import network_episode, plain_decider
    from nbv.models.config import PCNBVConfig
    from nbv.models.inference import for_inference
    from nbv.models.pcnbv import PCNBV
    from nbv.policies.network import NetworkPolicy

    torch.manual_seed(0)
    config = dict(k=4, growth=4, blocks=2, first_channels=8, attention_channels=8)
    net = PCNBV(PCNBVConfig(n_views=12, conv_channels=(32, 32), fc_channels=(32, 16), **config))
    net.eval()
    rng = np.random.default_rng(0)
    views = [rng.normal(size=(50, 3)).astype(np.float32) + i for i in range(12)]
    policy = NetworkPolicy(
        for_inference(net, "fp32"), input=kind, n_points=64, lmax=2, precision="fp32"
    )
    ours = network_episode(policy.decide, views, start=2)
    assert ours == network_episode(plain_decider(net, 64, kind, 2), views, start=2)
    assert len(set(ours)) == 10


@pytest.mark.slow
def test_network_rows_are_well_formed_on_tiny_networks(tmp_path):
    """Every network row exists with positive times and its floor or slowdown (not its speed)."""
    from tiny_nets import save_tiny_checkpoint

    from nbv.bench.network import LOAD_TARGET, network_rows

    rng = np.random.default_rng(0)
    views = [rng.normal(size=(30, 3)).astype(np.float32) + i for i in range(33)]
    nets = [("tiny", save_tiny_checkpoint(tmp_path / "p.pt"), 0.13),
            ("tiny-sph", save_tiny_checkpoint(tmp_path / "s.pt", "signature"), None)]  # fmt: skip
    rows = network_rows(views, nets, starts=(1, 5, 9), repeat=1)
    names = [r["name"] for r in rows]
    assert names == [
        "tiny 9-view episode (sampling + forwards)",
        "tiny-sph 9-view episode (sampling + forwards)",
        "tiny episodes, 3 in lockstep, float32 (per episode)",
        "tiny-sph episodes, 3 in lockstep, float32 (per episode)",
        "tiny episodes, 3 in lockstep, float32, 1 thread as an evaluation worker (per episode)",
        "tiny-sph episodes, 3 in lockstep, float32, 1 thread as an evaluation worker (per episode)",
        "tiny 9-view episode beside a busy process",
        "tiny-sph 9-view episode beside a busy process",
    ]
    for r in rows:
        assert r["ours"] > 0 and r["reference"] > 0
        assert r["ratio"] == pytest.approx(r["reference"] / r["ours"])
    for r in rows[2:6]:
        assert 0 < r["floor"] < r["ours"] and "FLOP floor" in r["note"]
        # The floor divides by the higher rate: never above the clock formula's floor.
        assert r["floor"] <= r["floor_of_clock"] and r["matmul_gflops"] > 0
    assert "1 core x" in rows[4]["note"]
    for r in rows[6:]:
        assert r["slowdown"] == pytest.approx(r["ours"] / r["reference"])
        assert r["target"] == pytest.approx(LOAD_TARGET * r["reference"])
    assert "| tiny episodes, 3 in lockstep" in format_table(rows)


def test_lockstep_episodes_equal_one_at_a_time_episodes():
    from nbv.bench.network import lockstep_episodes, network_episode

    views = [np.full((i + 1, 3), i, dtype=np.float32) for i in range(12)]

    def biggest_cloud_rule(cloud, state):  # depends on the episode's own cloud and state
        return int(np.flatnonzero(~state)[len(cloud) % int((~state).sum())])

    def many(clouds, states):
        return [biggest_cloud_rule(c, s) for c, s in zip(clouds, states, strict=True)]

    starts = [0, 4, 11]
    assert lockstep_episodes(many, views, starts) == [
        network_episode(biggest_cloud_rule, views, s) for s in starts
    ]


@pytest.mark.slow
def test_flop_count_equals_torch_flop_counter():
    import torch
    from torch.utils.flop_counter import FlopCounterMode

    from nbv.bench.floor import inference_flops, pcnbv_flops
    from nbv.models.config import PCNBVConfig
    from nbv.models.inference import for_inference
    from nbv.models.pcnbv import PCNBV

    torch.manual_seed(0)
    tiny = PCNBVConfig(n_views=12, k=4, growth=4, dense_layers=2, blocks=2, first_channels=8,
                       attention_channels=8, conv_channels=(32,), fc_channels=(32,))  # fmt: skip
    for config, n in ((PCNBVConfig(), 64), (tiny, 40)):
        net = PCNBV(config).eval()
        for model, count in ((net, pcnbv_flops), (for_inference(net, "fp32"), inference_flops)):
            with torch.inference_mode(), FlopCounterMode(display=False) as counter:
                model(torch.randn(1, n, 3), torch.zeros(1, config.n_views))
            assert count(config, n) == counter.get_total_flops()
    # The figure: a 512-point PCNBV forward is about 2.6 GFLOP.
    assert pcnbv_flops(PCNBVConfig(), 512) == 2_608_023_040
    # The evaluation form does 23 % less of it.
    assert inference_flops(PCNBVConfig(), 512) == 2_010_967_768


def test_peak_flops_formula():
    from nbv.bench.floor import peak_flops

    avx2 = "vendor_id\t: AuthenticAMD\ncpu MHz\t\t: 2596.130\nflags\t\t: sse avx2 fma avx512f\n"
    peak = peak_flops(avx2, cores=2)  # the clock of cpufreq, when readable, wins over cpu MHz
    assert peak.lanes == 8 and peak.cores == 2
    assert peak.flops == pytest.approx(2 * peak.ghz * 1e9 * 8 * 4)
    peak = peak_flops(avx2, max_khz=3_000_000, cores=2)
    assert peak.flops == pytest.approx(192e9) and "192 GFLOP/s" in peak.formula()
    intel = "vendor_id\t: GenuineIntel\nflags\t\t: sse avx2 fma avx512f\n"
    assert peak_flops(intel, max_khz=2_000_000, cores=1).flops == pytest.approx(128e9)
    assert peak_flops("flags\t: sse sse2\n", max_khz=1_000_000, cores=1).lanes == 4
    with pytest.raises(ValueError, match="no CPU flags"):
        peak_flops("model name\t: x\n", max_khz=1, cores=1)


def test_matmul_rate_is_the_flops_of_a_timed_product():
    from nbv.bench.floor import matmul_flops

    rate = matmul_flops(threads=1, shape=(64, 32, 16), repeat=2)
    # 2 M K N FLOPs in at least a nanosecond: positive and finite, and no faster than that.
    assert 0 < rate <= 2 * 64 * 32 * 16 / 1e-9
    with pytest.raises(ValueError, match="positive sizes"):
        matmul_flops(shape=(0, 4, 4))
    assert 0 < matmul_flops(threads=1, shape=(64, 32, 16), repeat=2, precision="bf16")
    with pytest.raises(ValueError, match="precision='fp16'"):
        matmul_flops(shape=(4, 4, 4), precision="fp16")


def test_floor_rate_is_the_highest_of_the_peak_and_the_products():
    from nbv.bench.floor import FloorRate, Peak, floor_rate

    peak = Peak(cores=1, ghz=2.0, lanes=8, flops=64e9)
    rate = FloorRate(peak, {"fp32": 80e9, "bf16": 150e9}, shape=(8, 4, 2))
    assert rate.flops == 150e9
    assert FloorRate(peak, {"fp32": 50e9}).flops == 64e9
    assert rate.describe() == (
        "150 GFLOP/s, the higher of (1 core x 2.00 GHz x 8 lanes x 2 (FMA) x 2 pipes = 64 GFLOP/s) "
        "and the 80 GFLOP/s of a 8x4x2 float32 matrix product and the 150 GFLOP/s of a 8x4x2 "
        "bfloat16 matrix product here"
    )
    measured = floor_rate(threads=1, precision="bf16", shape=(64, 32, 16))
    assert set(measured.matmul) == {"fp32", "bf16"} and measured.peak.cores == 1
    assert measured.flops == max(measured.peak.flops, *measured.matmul.values())
    assert set(floor_rate(threads=1, shape=(64, 32, 16)).matmul) == {"fp32"}


def test_a_training_step_counts_three_forwards_at_most_torchs_count_above():
    import torch
    from torch.utils.flop_counter import FlopCounterMode

    from nbv.bench.floor import pcnbv_flops, training_flops
    from nbv.models.config import PCNBVConfig
    from nbv.models.pcnbv import PCNBV

    config = PCNBVConfig()
    for n in (40, 64, 512):
        assert training_flops(config, n) == 3 * pcnbv_flops(config, n)
    # The full-size network on two 64-point samples, forward and backward, as torch counts them:
    # the estimate is 0.19 % above (no gradient of the first conv's input or the distances).
    torch.manual_seed(0)
    net = PCNBV(config).train()
    with FlopCounterMode(display=False) as counter:
        net(torch.randn(2, 64, 3), torch.zeros(2, config.n_views)).square().sum().backward()
    assert counter.get_total_flops() == 1_685_604_096
    assert 2 * training_flops(config, 64) == 1_688_768_256


def test_training_step_is_one_adam_step_on_the_squared_error():
    import copy

    import torch
    from tiny_nets import TINY_NET

    from nbv.bench.training import random_batch, training_step
    from nbv.models.config import PCNBVConfig
    from nbv.models.pcnbv import PCNBV

    torch.manual_seed(0)
    net = PCNBV(PCNBVConfig(n_views=12, **TINY_NET)).train()
    twin = copy.deepcopy(net)
    points, state, target = batch = random_batch(20, 12, batch=5, seed=3)
    assert points.shape == (5, 20, 3) and state.shape == target.shape == (5, 12)
    assert torch.equal(target[state == 1], torch.zeros(int(state.sum())))
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-2)
    loss = training_step(net, optimizer, batch, "fp32")
    expected = ((twin(points, state) - target) ** 2).sum(dim=1).mean()
    expected.backward()
    assert loss == pytest.approx(expected.item(), rel=1e-6)
    for (name, p), q in zip(net.named_parameters(), twin.parameters(), strict=True):
        torch.testing.assert_close(p.grad, q.grad, msg=name)
        # Adam's first step moves every weight with a gradient by about lr against its sign.
        moved = (q - p)[q.grad != 0]
        assert torch.allclose(moved, 1e-2 * q.grad[q.grad != 0].sign(), rtol=1e-2), name


@pytest.mark.parametrize(
    ("precision", "kind"), [("fp32", "float32"), ("bf16", "bfloat16 autocast")]
)
@pytest.mark.slow
def test_training_rows_are_well_formed_on_tiny_networks(tmp_path, precision, kind):
    """A training row per network with positive rates and its floor (not its speed)."""
    from tiny_nets import TINY_NET, save_tiny_checkpoint

    from nbv.bench.floor import pcnbv_flops
    from nbv.bench.training import training_rows
    from nbv.models.config import PCNBVConfig

    nets = [("tiny", save_tiny_checkpoint(tmp_path / "p.pt")),
            ("tiny-sph", save_tiny_checkpoint(tmp_path / "s.pt", "signature"))]  # fmt: skip
    rows = training_rows(nets, n_views=33, batch=4, precision=precision, threads=1, repeat=1)
    assert [r["name"] for r in rows] == [
        f"tiny training step (forward + backward + Adam), batch 4 x 64 points, {kind}",
        # lmax 2: 4 (2 + 1)^2 = 36 signature points
        f"tiny-sph training step (forward + backward + Adam), batch 4 x 36 points, {kind}",
    ]
    config = PCNBVConfig(n_views=33, **TINY_NET)
    for r, points in zip(rows, (64, 36), strict=True):
        assert r["points"] == points and r["batch"] == 4 and r["threads"] == 1
        assert r["forward_flops"] == pcnbv_flops(config, points)
        assert r["train_flops"] == 3 * r["forward_flops"]
        assert r["ours"] > 0 and r["samples_per_s"] == 4 / r["ours"]
        assert r["reference"] == r["floor"] and r["ratio"] == r["floor"] / r["ours"]
        assert r["floor_samples_per_s"] == 4 / r["floor"]
        # The floor divides by the higher rate: never above the clock formula's floor.
        assert 0 < r["floor"] <= r["floor_of_clock"] and r["matmul_gflops"] > 0
        assert r["precision"] == precision
        assert ("matmul_bf16_gflops" in r) == (precision == "bf16")
        assert r["note"].startswith(f"{4 / r['ours']:.1f} samples/s on 1 thread vs the FLOP")
        assert "1 core x" in r["note"]
    assert "| tiny training step" in format_table(rows)


@pytest.mark.slow
def test_configure_openmp_sets_a_passive_wait_before_torch_and_keeps_the_users():
    import subprocess
    import sys

    code = ("import os, sys; from nbv.models.threads import configure_openmp; "
            "first = configure_openmp(); import torch; "
            "print(first, configure_openmp(), os.environ['OMP_WAIT_POLICY'])")  # fmt: skip
    env = {k: v for k, v in __import__("os").environ.items() if k != "OMP_WAIT_POLICY"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.stdout.split() == ["True", "False", "PASSIVE"], out.stderr
    env["OMP_WAIT_POLICY"] = "ACTIVE"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.stdout.split() == ["True", "False", "ACTIVE"], out.stderr
