"""The benchmark's plain reference implementations agree with the fast paths they time."""

import numpy as np
import pytest

from nbv.bench.suite import format_table, numpy_fps, python_greedy, scipy_signature
from nbv.geometry.clouds import farthest_points
from nbv.geometry.sph import signature
from nbv.planning.set_cover import greedy_max_coverage


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
