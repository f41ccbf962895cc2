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


def test_unknown_loss():
    assert LOSSES == ("squared", "normalised", "listwise")
    with pytest.raises(ValueError, match="loss='rank': must be one of squared"):
        per_sample_loss("rank", TARGET, TARGET, STATE)
