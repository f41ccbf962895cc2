"""The training losses on values worked out by hand."""

import math

import pytest
import torch

from train.losses import LOSSES, batch_loss, per_sample_loss

TARGET = torch.tensor([[0.0, 0.2, 0.1, 0.1], [0.0, 0.0, 0.0, 0.0]])
STATE = torch.tensor([[1.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0]])


def test_squared_and_normalised():
    pred = torch.tensor([[0.0, 0.1, 0.1, 0.3], [0.5, 0.0, 0.0, 0.0]])
    squared = per_sample_loss("squared", pred, TARGET, STATE)
    torch.testing.assert_close(squared, torch.tensor([0.01 + 0.04, 0.25]))
    # Targets over the sample's largest gain: 0, 1, 0.5, 0.5; a sample without gain stays 0.
    normalised = per_sample_loss("normalised", pred, TARGET, STATE)
    torch.testing.assert_close(normalised, torch.tensor([0.81 + 0.16 + 0.04, 0.25]))
    assert float(batch_loss("squared", pred, TARGET, STATE)) == pytest.approx(0.15)


def test_listwise_is_cross_entropy_over_the_unvisited_views():
    # Logits equal to the log of the normalised gains give the minimum: the gains' entropy.
    weights = torch.tensor([0.5, 0.25, 0.25])
    pred = torch.tensor([[9.0, *weights.log().tolist()], [0.0] * 4]).requires_grad_()
    loss = batch_loss("listwise", pred, TARGET, STATE)
    entropy = -(weights * weights.log()).sum()
    assert loss.item() == pytest.approx(float(entropy))  # the gain-free sample takes no part
    loss.backward()
    assert pred.grad.abs().max() < 1e-6  # a minimum; the visited view's logit does not matter
    # Uniform logits: log 3 nats.
    uniform = per_sample_loss("listwise", torch.zeros(2, 4), TARGET, STATE)
    assert float(uniform[0]) == pytest.approx(math.log(3))
    assert float(uniform[1]) == 0.0


def test_pairwise_agrees_with_a_loop_over_the_pairs():
    generator = torch.Generator().manual_seed(0)
    pred = torch.randn(5, 7, generator=generator)
    # Gains with ties (rounded), some visited views, and a sample whose open views all gain alike.
    target = (torch.rand(5, 7, generator=generator) * 4).round() / 10
    state = (torch.rand(5, 7, generator=generator) < 0.3).float()
    target[4], state[4] = 0.3, torch.tensor([1.0, 0, 0, 0, 0, 0, 1])
    expected = []
    for p, t, s in zip(pred.tolist(), target.tolist(), state.tolist(), strict=True):
        open_ = [i for i in range(7) if s[i] == 0]
        terms = [math.log1p(math.exp(-(p[i] - p[j]))) for i in open_ for j in open_ if t[i] > t[j]]
        expected.append(sum(terms) / len(terms) if terms else 0.0)
    loss = per_sample_loss("pairwise", pred, target, state)
    torch.testing.assert_close(loss, torch.tensor(expected))
    # The gain-free sample takes no part in the batch's mean.
    assert float(batch_loss("pairwise", pred, target, state)) == pytest.approx(
        sum(expected[:4]) / 4
    )
    # Only the gains' order matters.
    torch.testing.assert_close(per_sample_loss("pairwise", pred, target.exp() * 3, state), loss)


def test_pairwise_on_values_worked_out_by_hand():
    # Open views 1, 2, 3 with gains 0.2, 0.1, 0.1: the ordered pairs are (1, 2) and (1, 3).
    pred = torch.tensor([[5.0, 1.0, 1.0, 0.0], [0.0] * 4])
    loss = per_sample_loss("pairwise", pred, TARGET, STATE)
    assert float(loss[0]) == pytest.approx((math.log(2) + math.log1p(math.exp(-1))) / 2)
    assert float(loss[1]) == 0.0  # two open views, both without gain: no pair


def test_unknown_loss():
    assert LOSSES == ("squared", "normalised", "listwise", "pairwise")
    with pytest.raises(ValueError, match="loss='rank': must be one of squared"):
        per_sample_loss("rank", TARGET, TARGET, STATE)


def test_the_weight_penalty_takes_the_encoders_matrices_or_every_matrix():
    from nbv.models.config import PCNBVConfig
    from nbv.models.pcnbv import PCNBV
    from train.losses import penalised, weight_penalty

    torch.manual_seed(0)
    sizes = dict(k=4, growth=4, dense_layers=2, blocks=2, first_channels=8, attention_channels=8)
    net = PCNBV(PCNBVConfig(n_views=5, conv_channels=(16,), fc_channels=(12,), **sizes))
    every, encoder = penalised(net, "all"), penalised(net, "encoder")
    # The fully connected head (here 16 -> 12 -> 5) is all that the encoder scope leaves free.
    assert [n for n in every if n not in encoder] == ["head.0.weight", "head.2.weight"]
    assert set(encoder) < set(every) and all(not n.startswith("head.") for n in encoder)
    params = dict(net.named_parameters())
    # Every matrix; biases, batch norm and the attention's gamma never.
    assert every == [n for n, p in params.items() if p.ndim > 1]
    assert {n.split(".")[0] for n in encoder} == {"features", "attention", "convs"}
    head = sum(float((params[n].detach() ** 2).sum()) for n in ("head.0.weight", "head.2.weight"))
    difference = weight_penalty(net, "all") - weight_penalty(net, "encoder")
    assert difference.item() == pytest.approx(head, rel=1e-5)
    # The encoder's penalty sends no gradient into the head.
    weight_penalty(net, "encoder").backward()
    assert (
        params["head.0.weight"].grad is None
        and params["convs.0.linear.weight"].grad.abs().sum() > 0
    )
    with pytest.raises(ValueError, match="l2_scope='head': must be one of all, encoder"):
        penalised(net, "head")
