"""A network's views matched with another viewspace's by direction (nbv.policies.view_matching):
exact on hand-made cases, the identity on the training viewspace, and agreement with a
brute-force loop on the shipped permuted viewspace."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from nbv.geometry.viewspace import get_viewspace
from nbv.policies.network import NetworkPolicy
from nbv.policies.registry import METHODS
from nbv.policies.view_matching import NEIGHBOURS, MatchedNetworkPolicy, ViewMap

SQ = np.sqrt(0.5)


def _brute_force(trained: np.ndarray, views: np.ndarray, values: np.ndarray, k: int):
    """Each view's Shepard interpolation over its k nearest training views, one view at a time,
    with the angle from atan2(|a x b|, a . b)."""
    out = []
    for v in views / np.linalg.norm(views, axis=1, keepdims=True):
        t = trained / np.linalg.norm(trained, axis=1, keepdims=True)
        angles = np.array(
            [np.degrees(np.arctan2(np.linalg.norm(np.cross(v, u)), v @ u)) for u in t]
        )
        order = sorted(range(len(t)), key=lambda j: (angles[j], j))[:k]
        if angles[order[0]] < 1e-6:
            out.append(values[order[0]])
            continue
        w = np.array([1.0 / angles[j] ** 2 for j in order])
        out.append(float(np.dot(w / w.sum(), values[order])))
    return np.array(out)


def test_on_the_training_viewspace_the_map_is_the_identity():
    original = get_viewspace("original")
    view_map = ViewMap.between(original, 2.5 * original)  # lengths do not count
    np.testing.assert_array_equal(view_map.nearest, np.arange(33))
    values = np.random.default_rng(0).normal(size=(4, 33))
    np.testing.assert_array_equal(view_map.scores(values), values)
    state = np.zeros(33, bool)
    state[[0, 7, 31]] = True
    np.testing.assert_array_equal(view_map.shown(state), state)


def test_hand_made_directions():
    trained = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    views = np.array([[SQ, SQ, 0], [0, 0, 2.0], [1.0, 1e-3, 0]])
    view_map = ViewMap.between(trained, views, k=2)
    # Midway between x and y (45 degrees from each): their mean; on z: z's value exactly.
    np.testing.assert_allclose(view_map.scores(np.array([2.0, 4.0, 8.0])), [3.0, 8.0, 2.0],
                               atol=1e-5)  # fmt: skip
    np.testing.assert_array_equal(view_map.nearest, [0, 2, 0])
    np.testing.assert_array_equal(view_map.shown(np.array([False, True, True])),
                                  [True, False, True])  # fmt: skip
    np.testing.assert_allclose(view_map.weights.sum(axis=1), 1.0)


def test_agrees_with_a_brute_force_loop_on_the_permuted_viewspace():
    original, permuted = get_viewspace("original"), get_viewspace("permuted")
    values = np.random.default_rng(1).normal(size=33)
    view_map = ViewMap.between(original, permuted)
    expected = _brute_force(original, permuted, values, NEIGHBOURS)
    np.testing.assert_allclose(view_map.scores(values), expected, atol=1e-9)
    # No permuted view is a training view (they keep 5 degrees away): every score interpolates.
    assert (view_map.weights[:, 0] < 1).all()
    # Each captured permuted view shows exactly its nearest training view.
    for v in range(33):
        state = np.zeros(33, bool)
        state[v] = True
        shown = view_map.shown(state)
        assert shown.sum() == 1
        angles = np.degrees(np.arccos(np.clip(original @ permuted[v], -1, 1)))
        assert int(np.flatnonzero(shown)[0]) == int(np.argmin(angles))


def test_the_matched_methods_name_the_network_they_run():
    for name, network in (("pcnbv_matched", "pcnbv"), ("pcnbv_sph_matched", "pcnbv_sph")):
        method = METHODS[name]
        assert method.matched and method.network == network and method.networks == (network,)
        assert method.network_input is None


@pytest.mark.parametrize("k", [1, 3, 40])
def test_interpolation_stays_within_the_neighbours_values(k):
    original, permuted = get_viewspace("original"), get_viewspace("permuted")
    values = np.random.default_rng(k).uniform(-1, 1, size=(5, 33))
    view_map = ViewMap.between(original, permuted, k=k)
    assert view_map.neighbours.shape == (33, min(k, 33))
    out = view_map.scores(values)
    near = values[:, view_map.neighbours]
    assert (out >= near.min(axis=-1) - 1e-12).all() and (out <= near.max(axis=-1) + 1e-12).all()
    if k == 1:
        np.testing.assert_array_equal(out, values[:, view_map.nearest])


def test_a_network_of_another_size_than_its_training_viewspace_is_refused():
    network = NetworkPolicy(model=SimpleNamespace(config=SimpleNamespace(n_views=40)))
    with pytest.raises(
        ValueError, match="the network has 40 outputs but its training viewspace 33"
    ):
        MatchedNetworkPolicy(network, get_viewspace("original"))
