"""Tests of nbv.models: the PCNBV network, masked_argmax and checkpoints.

Tiny configs keep everything fast on CPU; the default config is only built to check its sizes.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from nbv.models.checkpoints import CheckpointError, load_checkpoint, save_checkpoint
from nbv.models.config import PCNBVConfig
from nbv.models.inference import for_inference, masked_argmax
from nbv.models.layers import DenseEdgeConv, max_over, max_over_neighbours
from nbv.models.neighbours import knn_indices, smallest_indices
from nbv.models.pcnbv import PCNBV, count_parameters
from nbv.models.precision import autocast, flush_denormals, resolve_precision

TINY = PCNBVConfig(
    n_views=7,
    k=4,
    growth=4,
    dense_layers=3,
    blocks=2,
    first_channels=8,
    attention_channels=8,
    conv_channels=(32, 32),
    fc_channels=(32, 16),
)


@pytest.fixture(autouse=True)
def one_thread():
    """Tiny tensors gain nothing from threads, and on a shared 2-core machine OpenMP's waiting
    threads make them many times slower."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def tiny(**changes: object) -> PCNBV:
    values = TINY.to_dict() | changes
    return PCNBV(PCNBVConfig.from_dict(values))


def random_batch(
    b: int, n: int, v: int, seed: int = 0
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Points (B, N, 3), a 0/1 view state (B, V) with view 0 always visited, targets (B, V)."""
    g = torch.Generator().manual_seed(seed)
    points = torch.randn(b, n, 3, generator=g)
    state = (torch.rand(b, v, generator=g) < 0.3).float()
    state[:, 0] = 1.0
    return points, state, torch.rand(b, v, generator=g)


def sse(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    return ((pred - target) ** 2).sum(dim=1).mean()


def train_steps(model: PCNBV, steps: int, seed: int = 0, lr: float = 1e-3) -> None:
    points, state, target = random_batch(4, 24, model.config.n_views, seed)
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    model.train()
    for _ in range(steps):
        opt.zero_grad()
        sse(model(points, state), target).backward()
        opt.step()


# ---- shapes and sizes ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("b", "n", "v", "batch_norm"),
    [(1, 4, 7, True), (3, 20, 33, True), (2, 16, 1, False), (5, 9, 4, False)],
)
def test_output_shape(b: int, n: int, v: int, batch_norm: bool) -> None:
    torch.manual_seed(0)
    model = tiny(n_views=v, batch_norm=batch_norm)
    points, state, _ = random_batch(b, n, v)
    for mode in (model.train, model.eval):
        mode()
        out = model(points, state.bool())
        assert out.shape == (b, v)
        assert out.dtype == torch.float32
        assert torch.isfinite(out).all()


def test_default_config_channel_counts() -> None:
    cfg = PCNBVConfig()
    assert (cfg.n_views, cfg.k, cfg.growth, cfg.dense_layers, cfg.blocks) == (33, 16, 12, 3, 4)
    assert cfg.block_out_channels == 60
    assert cfg.point_channels == 264
    assert cfg.concat_channels == 561

    torch.manual_seed(0)
    model = PCNBV().eval()
    seen: dict[str, tuple[int, ...]] = {}

    def record(name: str):
        def hook(module, inputs, output) -> None:
            seen[name] = tuple(inputs[0].shape) + tuple(output.shape)

        return hook

    model.features.register_forward_hook(record("features"))
    model.attention.register_forward_hook(record("attention"))
    model.convs.register_forward_hook(record("convs"))
    model.head.register_forward_hook(record("head"))
    for i, block in enumerate(model.features.blocks):
        block.register_forward_hook(record(f"block{i}"))
    points, state, _ = random_batch(2, 20, 33)
    with torch.no_grad():
        model(points, state)
    assert seen["features"] == (2, 20, 3, 2, 20, 264)
    assert seen["attention"] == (2, 20, 561, 2, 20, 561)
    assert seen["convs"] == (2, 20, 561, 2, 20, 1024)
    assert seen["head"] == (2, 1024, 2, 33)
    # Every dense block reads 24 channels and writes 3 * 12 + 24 = 60.
    for i in range(4):
        assert seen[f"block{i}"] == (2, 20, 24, 2, 20, 60)
    # The squeeze convs read l1, l2, l3 = 84, 144, 204 channels.
    assert [s.linear.in_features for s in model.features.squeeze] == [84, 144, 204]
    assert model.attention.query.out_features == 140
    assert model.attention.key.out_features == 140
    assert model.attention.value.out_features == 561
    assert [m.out_features for m in model.head if isinstance(m, torch.nn.Linear)] == [512, 256, 33]


def test_count_parameters_default_model() -> None:
    # Each 1x1 conv with batch norm: a * b weights (no bias) + 2 b batch norm scale and shift.
    def conv_bn(a: int, b: int) -> int:
        return a * b + 2 * b

    def linear(a: int, b: int) -> int:
        return a * b + b

    first = conv_bn(3, 24)
    block = conv_bn(48, 12) + conv_bn(36, 12) + conv_bn(48, 12)
    squeeze = conv_bn(84, 24) + conv_bn(144, 24) + conv_bn(204, 24)
    attention = 2 * linear(561, 140) + linear(561, 561) + 1
    convs = conv_bn(561, 1024) + conv_bn(1024, 1024)
    head = linear(1024, 512) + linear(512, 256) + linear(256, 33)
    expected = first + 4 * block + squeeze + attention + convs + head
    model = PCNBV()
    assert count_parameters(model) == expected == 2_781_644
    for p in model.head.parameters():
        p.requires_grad_(False)
    assert count_parameters(model) == expected - head


# ---- the parts against brute force --------------------------------------------------------------


def test_knn_indices_match_brute_force() -> None:
    g = torch.Generator().manual_seed(1)
    x = torch.randn(2, 30, 5, generator=g)
    idx = knn_indices(x, 6)
    assert idx.shape == (2, 30, 6)
    for b in range(2):
        dist = ((x[b, :, None, :] - x[b, None, :, :]) ** 2).sum(-1)
        for i in range(30):
            expected = set(np.argsort(dist[i].numpy(), kind="stable")[:6].tolist())
            assert set(idx[b, i].tolist()) == expected
            assert i in expected


def test_smallest_indices_select_what_topk_selects() -> None:
    g = torch.Generator().manual_seed(2)
    for shape, k in (((3, 40, 512), 16), ((700, 64), 4), ((2, 5, 30), 6), ((4, 16), 16),
                     ((30, 64), 16)):  # fmt: skip
        values = torch.randn(*shape, generator=g)
        values[..., 7] = -math.inf  # the forced self-distance
        values[..., :3] = torch.round(values[..., :3])  # ties, also at the k-th place
        expected = values.topk(k, dim=-1, largest=False).values
        idx = smallest_indices(values, k)
        assert idx.shape == (*shape[:-1], k)
        assert torch.equal(values.gather(-1, idx).sort(-1).values, expected)
        # No index twice in a row.
        assert (idx.sort(-1).values.diff(dim=-1) > 0).all()
    # Rows of four distinct values only: whole groups tie at the k-th place.
    values = torch.randint(0, 4, (64, 512), generator=g).float()
    idx = smallest_indices(values, 16)
    expected = values.topk(16, dim=-1, largest=False).values
    assert torch.equal(values.gather(-1, idx).sort(-1).values, expected)
    assert (idx.sort(-1).values.diff(dim=-1) > 0).all()


def test_max_over_neighbours_is_amax_over_the_neighbour_axis() -> None:
    g = torch.Generator().manual_seed(5)
    for k in (1, 2, 3, 7, 16, 17):  # odd sizes leave one entry over at some halving
        x = torch.randn(2, 9, k, 12, generator=g)
        x[0, 0, -1, 0] = 50.0  # the maximum in the last entry
        assert torch.equal(max_over_neighbours(x), x.amax(2))
    x = torch.randn(2, 3, 5, 4, generator=g, requires_grad=True)
    max_over_neighbours(x).sum().backward()
    assert torch.equal(x.grad.sum(2), torch.ones(2, 3, 4))  # one max a channel gets the gradient


def test_knn_of_batches_searched_in_groups_match_brute_force() -> None:
    x = torch.randn(6, 512, 3, generator=torch.Generator().manual_seed(3))  # two groups of 4
    idx = knn_indices(x, 16)
    dist = torch.cdist(x.double(), x.double())
    dist.diagonal(dim1=1, dim2=2).fill_(-1.0)
    expected = dist.topk(16, dim=-1, largest=False).values
    torch.testing.assert_close(dist.gather(-1, idx).sort(-1).values, expected)


def test_knn_always_includes_self_with_duplicates() -> None:
    # Five copies of the same point: every one of them must count itself as a neighbour.
    x = torch.zeros(1, 8, 3)
    x[0, 5:] = torch.tensor([[1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    idx = knn_indices(x, 2)
    for i in range(8):
        assert i in idx[0, i].tolist()


def test_max_over_same_values_and_gradient_to_the_max() -> None:
    x = torch.tensor([[[1.0, 5.0], [3.0, 2.0], [0.0, 7.0]]], requires_grad=True)
    with torch.no_grad():
        plain = max_over(x, 1)
    out = max_over(x, 1)
    assert torch.equal(plain, out.detach())
    assert out.tolist() == [[3.0, 7.0]]
    out.sum().backward()
    assert x.grad.tolist() == [[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]]


def reference_dense_block(block: DenseEdgeConv, x: torch.Tensor) -> torch.Tensor:
    """The dense EdgeConv block written the long way: explicit edge features, explicit tiling
    and concatenation, neighbours by brute-force distances."""
    b, n, c = x.shape
    dist = ((x[:, :, None, :] - x[:, None, :, :]) ** 2).sum(-1)
    idx = dist.argsort(dim=-1, stable=True)[:, :, : block.k]
    neighbours = torch.stack([x[i][idx[i]] for i in range(b)])
    centre = x[:, :, None, :].repeat(1, 1, block.k, 1)
    y = torch.cat([neighbours - centre, centre], dim=-1)
    y = torch.cat([block.layers[0](y), centre], dim=-1)
    for layer in block.layers[1:]:
        y = torch.cat([layer(y), y], dim=-1)
    return y.max(dim=2).values


@pytest.mark.parametrize(("batch_norm", "train"), [(True, True), (True, False), (False, True)])
def test_dense_block_matches_brute_force(batch_norm: bool, train: bool) -> None:
    torch.manual_seed(2)
    block = DenseEdgeConv(c_in=6, growth=5, layers=3, k=4, batch_norm=batch_norm)
    x = torch.randn(3, 17, 6)
    if batch_norm:
        # Non-trivial running statistics and affine parameters for the eval-mode comparison.
        block.train()
        block(x * 2 + 1)
        for m in block.modules():
            if isinstance(m, torch.nn.BatchNorm1d):
                torch.nn.init.uniform_(m.weight, 0.5, 1.5)
                torch.nn.init.uniform_(m.bias, -0.5, 0.5)
    block.train(train)
    out = block(x)
    assert out.shape == (3, 17, 3 * 5 + 6)
    torch.testing.assert_close(out, reference_dense_block(block, x), atol=1e-5, rtol=1e-5)


def test_attention_starts_as_identity_and_matches_formula() -> None:
    torch.manual_seed(3)
    model = tiny()
    att = model.attention
    x = torch.randn(2, 10, TINY.concat_channels)
    torch.testing.assert_close(att(x), x, rtol=0, atol=0)
    with torch.no_grad():
        att.gamma.fill_(0.7)
    q, k, v = att.query(x), att.key(x), att.value(x)
    expected = 0.7 * torch.softmax(q @ k.transpose(1, 2), dim=-1) @ v + x
    torch.testing.assert_close(att(x), expected, atol=1e-5, rtol=1e-5)


# ---- invariances --------------------------------------------------------------------------------


def test_permutation_invariance_over_points() -> None:
    torch.manual_seed(4)
    model = tiny()
    train_steps(model, 3)  # non-trivial batch norm statistics
    with torch.no_grad():
        model.attention.gamma.fill_(0.5)  # make the attention path count
    model.eval()
    points, state, _ = random_batch(3, 40, TINY.n_views, seed=5)
    perm = torch.randperm(40)
    with torch.no_grad():
        out = model(points, state)
        out_perm = model(points[:, perm], state)
        other_state = model(points, 1.0 - state)
    torch.testing.assert_close(out_perm, out, atol=1e-5, rtol=0)
    # The view state does change the output, so the comparison above is not vacuous.
    assert (other_state - out).abs().max() > 1e-3


def test_input_normalisation() -> None:
    points, state, _ = random_batch(2, 30, TINY.n_views, seed=6)
    normed = PCNBV.normalize(points)
    torch.testing.assert_close(normed.mean(dim=1), torch.zeros(2, 3), atol=1e-6, rtol=0)
    torch.testing.assert_close(normed.norm(dim=-1).amax(dim=1), torch.ones(2))
    same = torch.full((1, 5, 3), 2.5)
    torch.testing.assert_close(PCNBV.normalize(same), torch.zeros(1, 5, 3), rtol=0, atol=0)

    torch.manual_seed(6)
    model = tiny().eval()
    moved = points * 3.0 + torch.tensor([1.0, -2.0, 0.5])
    with torch.no_grad():
        torch.testing.assert_close(model(moved, state), model(points, state), atol=1e-5, rtol=0)
    raw = tiny(normalize_input=False).eval()
    with torch.no_grad():
        assert (raw(moved, state) - raw(points, state)).abs().max() > 1e-3


def test_bool_and_float_view_state_agree() -> None:
    torch.manual_seed(7)
    model = tiny().eval()
    points, state, _ = random_batch(2, 12, TINY.n_views)
    with torch.no_grad():
        torch.testing.assert_close(model(points, state.bool()), model(points, state))


# ---- training -----------------------------------------------------------------------------------


def test_gradients_reach_every_parameter() -> None:
    torch.manual_seed(8)
    model = tiny().train()
    points, state, target = random_batch(3, 16, TINY.n_views, seed=8)

    # At initialisation gamma = 0, so the attention's query, key and value get exactly zero
    # gradient while gamma itself gets a non-zero one: the first Adam step moves gamma off 0.
    sse(model(points, state), target).backward()
    att = model.attention
    assert att.gamma.grad is not None and att.gamma.grad.abs() > 0
    for p in (*att.query.parameters(), *att.key.parameters(), *att.value.parameters()):
        assert p.grad is not None and torch.count_nonzero(p.grad) == 0

    # With gamma away from 0 (as after the first step) every parameter gets a gradient.
    model.zero_grad(set_to_none=True)
    with torch.no_grad():
        att.gamma.fill_(0.5)
    sse(model(points, state), target).backward()
    for name, p in model.named_parameters():
        assert p.grad is not None, name
        assert torch.isfinite(p.grad).all(), name
        assert p.grad.abs().sum() > 0, name


def test_tiny_model_overfits_a_few_samples() -> None:
    torch.manual_seed(9)
    model = tiny().train()
    points, state, target = random_batch(6, 24, TINY.n_views, seed=9)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    losses = []
    for _ in range(100):
        opt.zero_grad()
        loss = sse(model(points, state), target)
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < 0.1 * losses[0], (losses[0], losses[-1])


# ---- masked_argmax ------------------------------------------------------------------------------


def test_masked_argmax_matches_brute_force_and_skips_visited() -> None:
    rng = np.random.default_rng(10)
    scores = rng.normal(size=(200, 9)).astype(np.float32)
    scores[rng.random(scores.shape) < 0.2] = 5.0  # ties
    state = rng.random((200, 9)) < 0.6
    state[np.arange(200), rng.integers(0, 9, 200)] = False  # at least one free view a row
    chosen = masked_argmax(torch.from_numpy(scores), torch.from_numpy(state))
    assert chosen.shape == (200,) and chosen.dtype == torch.int64
    for row in range(200):
        free = [v for v in range(9) if not state[row, v]]
        best = max(free, key=lambda v: (scores[row, v], -v))  # first among equal scores
        assert chosen[row].item() == best


def test_masked_argmax_with_minus_inf_scores() -> None:
    scores = torch.tensor([[5.0, -math.inf, -math.inf], [-math.inf, -math.inf, 2.0]])
    state = torch.tensor([[1, 0, 0], [0, 1, 1]])
    assert masked_argmax(scores, state).tolist() == [1, 0]


def test_masked_argmax_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match=r"no unvisited view left in samples \[1\]"):
        masked_argmax(torch.zeros(2, 3), torch.tensor([[1, 0, 1], [1, 1, 1]]))
    with pytest.raises(ValueError, match="NaN"):
        masked_argmax(torch.tensor([[float("nan"), 1.0]]), torch.tensor([[0, 0]]))
    with pytest.raises(ValueError, match=r"\(2, 3\) and \(2, 4\)"):
        masked_argmax(torch.zeros(2, 3), torch.zeros(2, 4))


# ---- input validation ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("points_shape", "state_shape", "message"),
    [
        ((2, 10), (2, 7), r"points must have shape \(B, N, 3\), got \(2, 10\)"),
        ((2, 10, 2), (2, 7), r"points must have shape \(B, N, 3\), got \(2, 10, 2\)"),
        ((2, 10, 3), (2, 33), r"view_state must have shape \(B, V\) = \(2, 7\), got \(2, 33\)"),
        ((2, 10, 3), (3, 7), r"view_state must have shape \(B, V\) = \(2, 7\), got \(3, 7\)"),
        ((2, 3, 3), (2, 7), r"at least k = 4 points a sample, got shape \(2, 3, 3\)"),
    ],
)
def test_forward_rejects_bad_shapes(
    points_shape: tuple[int, ...], state_shape: tuple[int, ...], message: str
) -> None:
    model = tiny()
    with pytest.raises(ValueError, match=message):
        model(torch.zeros(points_shape), torch.zeros(state_shape))


def test_forward_rejects_wrong_dtype() -> None:
    with pytest.raises(ValueError, match="points must be torch.float32 .* got torch.float64"):
        tiny()(torch.zeros(1, 8, 3, dtype=torch.float64), torch.zeros(1, 7))
    model = tiny().double()
    assert model(torch.zeros(1, 8, 3, dtype=torch.float64), torch.zeros(1, 7)).dtype == (
        torch.float64
    )


def test_forward_rejects_non_finite_points() -> None:
    points = torch.zeros(1, 8, 3)
    points[0, 3, 1] = float("nan")
    with pytest.raises(ValueError, match="points must be finite"):
        tiny()(points, torch.zeros(1, 7))


def test_config_validation_and_round_trip() -> None:
    assert PCNBVConfig.from_dict(TINY.to_dict()) == TINY
    assert PCNBVConfig(conv_channels=[8, 8]).conv_channels == (8, 8)
    with pytest.raises(ValueError, match="PCNBVConfig.k must be a positive int, got 0"):
        PCNBVConfig(k=0)
    with pytest.raises(ValueError, match="PCNBVConfig.fc_channels"):
        PCNBVConfig(fc_channels=(8, -1))
    with pytest.raises(ValueError, match="PCNBVConfig.batch_norm must be a bool"):
        PCNBVConfig(batch_norm=1)
    with pytest.raises(ValueError, match=r"unknown PCNBVConfig keys \['width'\]"):
        PCNBVConfig.from_dict({"width": 3})


# ---- checkpoints --------------------------------------------------------------------------------

EXTRA = {
    "train": {"lr": 1e-3, "batch_size": 32, "score": "vig", "folds": [0, 1]},
    "dataset": {"path": "data/generated/train.h5", "schema_version": 1},
    "epoch": 12,
    "metrics": {"val_loss": 0.25},
}


def test_checkpoint_round_trip(tmp_path: Path) -> None:
    torch.manual_seed(11)
    model = tiny()
    train_steps(model, 2)
    with torch.no_grad():
        model.attention.gamma.fill_(0.3)
    model.eval()
    path = tmp_path / "runs" / "model.pt"
    save_checkpoint(path, model, EXTRA)
    assert sorted(p.name for p in path.parent.iterdir()) == ["model.pt"]  # no temporary left

    loaded, extra = load_checkpoint(path, n_views=TINY.n_views)
    assert extra == EXTRA
    assert loaded.config == model.config
    assert not loaded.training
    points, state, _ = random_batch(2, 20, TINY.n_views, seed=12)
    with torch.no_grad():
        assert torch.equal(loaded(points, state), model(points, state))

    # Overwriting an existing checkpoint replaces it.
    save_checkpoint(path, tiny(), {"epoch": 13})
    assert load_checkpoint(path)[1] == {"epoch": 13}


def test_save_checkpoint_rejects_unreadable_extra(tmp_path: Path) -> None:
    path = tmp_path / "model.pt"
    with pytest.raises(TypeError, match=r"extra\['metrics'\]\['loss'\] is a float32"):
        save_checkpoint(path, tiny(), {"metrics": {"loss": np.float32(1.0)}})
    with pytest.raises(TypeError, match=r"extra\['out'\] is a PosixPath"):
        save_checkpoint(path, tiny(), {"out": tmp_path})
    assert list(tmp_path.iterdir()) == []


def test_load_checkpoint_errors_name_the_file(tmp_path: Path) -> None:
    missing = tmp_path / "missing.pt"
    with pytest.raises(CheckpointError, match=f"{missing} does not exist or is not a file"):
        load_checkpoint(missing)

    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(b"this is not a torch file" * 10)
    with pytest.raises(CheckpointError, match=f"{corrupt}.*not a readable torch file"):
        load_checkpoint(corrupt)

    truncated = tmp_path / "truncated.pt"
    save_checkpoint(truncated, tiny(), EXTRA)
    truncated.write_bytes(truncated.read_bytes()[:500])
    with pytest.raises(CheckpointError, match=f"{truncated}.*not a readable torch file"):
        load_checkpoint(truncated)

    foreign = tmp_path / "foreign.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    with pytest.raises(CheckpointError, match=f"{foreign}.*not a PCNBV checkpoint"):
        load_checkpoint(foreign)

    good = tmp_path / "good.pt"
    save_checkpoint(good, tiny(), EXTRA)
    with pytest.raises(CheckpointError, match=f"{good} is a network for 7 views, expected 33"):
        load_checkpoint(good, n_views=33)

    # Weights of one config under another config's name.
    payload = torch.load(good, weights_only=True)
    payload["config"]["growth"] = 5
    mismatched = tmp_path / "mismatched.pt"
    torch.save(payload, mismatched)
    with pytest.raises(CheckpointError, match=f"{mismatched} weights do not fit its config"):
        load_checkpoint(mismatched)

    payload["config"] = {"n_views": 0}
    bad_config = tmp_path / "bad_config.pt"
    torch.save(payload, bad_config)
    with pytest.raises(CheckpointError, match=f"{bad_config} has an invalid config"):
        load_checkpoint(bad_config)

    payload = torch.load(good, weights_only=True)
    del payload["state_dict"]["head.0.weight"]
    missing_key = tmp_path / "missing_key.pt"
    torch.save(payload, missing_key)
    with pytest.raises(CheckpointError, match=f"{missing_key} weights do not fit.*head.0.weight"):
        load_checkpoint(missing_key)


def test_checkpoint_error_is_a_value_error() -> None:
    assert issubclass(CheckpointError, ValueError)


# ---- precision ------------------------------------------------------------------------------


def test_resolve_precision() -> None:
    assert resolve_precision("fp32") == "fp32"
    assert resolve_precision("bf16") == "bf16"
    assert resolve_precision("auto") in ("fp32", "bf16")
    with pytest.raises(ValueError, match="precision='fp16'.*auto, fp32, bf16"):
        resolve_precision("fp16")


def test_bf16_autocast_keeps_neighbours_and_head_in_fp32() -> None:
    torch.manual_seed(0)
    model = tiny(n_views=9).eval()
    points, state, _ = random_batch(3, 40, 9)
    features = torch.randn(2, 50, 8)
    with torch.no_grad():
        exact = model(points, state)
        with autocast("bf16"):
            approx = model(points, state)
            idx = knn_indices(features, 6)
    assert approx.dtype == torch.float32
    # bfloat16 keeps ~3 significant digits in the convolutions; the head adds no rounding.
    assert torch.allclose(approx, exact, atol=0.05 * exact.abs().max().item())
    assert torch.equal(idx.sort(-1).values, knn_indices(features, 6).sort(-1).values)
    with autocast("fp32"), torch.no_grad():
        assert torch.equal(model(points, state), exact)


def test_inference_copy_folds_batch_norm_and_predicts_the_same() -> None:
    torch.manual_seed(0)
    model = tiny(n_views=9)
    train_steps(model, 5)  # batch-norm running statistics away from their defaults
    model.eval()
    with torch.no_grad():
        model.attention.gamma.fill_(0.7)  # trained nets keep it near 0; make the path count
    points, state, _ = random_batch(3, 40, 9, seed=1)
    with torch.no_grad():
        exact = model(points, state)
        fast = for_inference(model, "fp32")
        torch.testing.assert_close(fast(points, state), exact, rtol=1e-5, atol=1e-6)
        assert not any(isinstance(m, torch.nn.BatchNorm1d) for m in fast.modules())
        assert all(not p.requires_grad for p in fast.parameters())
        assert fast.conv_points.dtype == torch.float32  # float32: the rewritten form
        half = for_inference(model, "bf16")  # bfloat16: the network's own form
        assert half.convs[0].linear.weight.dtype == torch.bfloat16
        assert half.attention.query.weight.dtype == torch.bfloat16
        assert half.head[0].weight.dtype == torch.float32
        assert half.features.first.linear.weight.dtype == torch.float32
        with autocast("bf16"):
            approx = half(points, state)
        assert torch.allclose(approx, exact, atol=0.05 * exact.abs().max().item())
        # The rewriting is exact in real arithmetic: in float64 the two agree to 1e-12.
        wide = copy.deepcopy(model).double()
        x64, s64 = points.double(), state.double()
        torch.testing.assert_close(
            for_inference(wide, "fp32")(x64, s64), wide(x64, s64), rtol=1e-12, atol=1e-12
        )
    # The original is untouched.
    assert model.convs[0].norm is not None and model.convs[0].linear.weight.requires_grad


def test_inference_copy_drops_only_constant_parts() -> None:
    """A view state or global feature change reaches the output through the folded constants:
    the rewritten network answers every input as the original does."""
    torch.manual_seed(3)
    model = tiny(n_views=9).eval()
    with torch.no_grad():
        model.attention.gamma.fill_(-1.3)
        fast = for_inference(model, "fp32")
        points, state, _ = random_batch(4, 30, 9, seed=5)
        for s in (state, 1 - state, torch.zeros_like(state)):
            torch.testing.assert_close(fast(points, s), model(points, s), rtol=1e-5, atol=1e-6)
        with pytest.raises(ValueError, match="view_state must have shape"):
            fast(points, state[:, :4])


def test_flush_denormals_is_scoped() -> None:
    tiny_value = torch.tensor([1e-40])
    with flush_denormals():
        with flush_denormals():
            pass
        flushed = (tiny_value * 1.0).item()  # still on after the inner block
    assert (tiny_value * 1.0).item() > 0.0
    supported = torch.set_flush_denormal(False)  # True where the CPU has FTZ/DAZ (x86)
    if supported:
        assert flushed == 0.0
