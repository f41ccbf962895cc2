"""Batched network decisions: one forward pass for the states of K episodes chooses what K
one-at-a-time decisions choose (float32, the shipped weights, many states of rendered models)."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from datagen import INFOGAIN, make_tiny_dataset
from tiny_nets import save_tiny_checkpoint

import nbv.dataset
from nbv.assets.meshes import Mesh, normalise
from nbv.assets.synthetic import build, catalogue
from nbv.assets.weights import shipped_weights
from nbv.geometry.camera import Intrinsics, backproject, viewspace_poses
from nbv.geometry.viewspace import original_viewspace
from nbv.policies.conditioned_network import ConditionedPolicy
from nbv.policies.episode import EPISODE_VIEWS, EpisodeState, run_episode
from nbv.policies.infogain import InfoGainPolicy
from nbv.policies.inputs import NO_SPREAD
from nbv.policies.network import MAX_BATCH, NetworkPolicy, chunk_size

log = logging.getLogger(__name__)

#: A small camera: clouds of thousands of points a view, rendered in well under a second.
CAMERA = Intrinsics.centred(160, 120, 119.0)
#: Largest difference allowed between a batched and a one-at-a-time predicted gain (float32
#: sums in another order differ in the last bits: 1e-7 was measured).
GAIN_TOL = 1e-5


@pytest.fixture(scope="module")
def rendered_views() -> list[list[np.ndarray]]:
    """The 33 original views (float32 world points) of one synthetic model of each of six
    categories, ray cast at 160 x 120."""
    poses = viewspace_poses(original_viewspace())
    firsts = {}
    for entry in catalogue():
        firsts.setdefault(entry.category, entry)
    from nbv.render.raycast import render_raycast

    models = []
    for entry in list(firsts.values())[:6]:
        mesh, _, _ = normalise(Mesh(*build(entry, 0)))
        depth = render_raycast(mesh.vertices, mesh.faces, poses, CAMERA)
        models.append(
            [
                backproject(d, CAMERA, p).astype(np.float32)
                for d, p in zip(depth, poses, strict=True)
            ]
        )
    return models


def random_states(models, per_model: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """(cloud, view state) pairs of 1 to 9 random visited views of each model."""
    rng = np.random.default_rng(seed)
    states = []
    for views in models:
        for _ in range(per_model):
            order = rng.choice(len(views), rng.integers(1, 10), replace=False)
            state = np.zeros(len(views), dtype=bool)
            state[order] = True
            states.append((np.concatenate([views[v] for v in order]), state))
    return states


@pytest.mark.parametrize("method", ["pcnbv", "pcnbv_sph"])
@pytest.mark.slow
def test_batched_gains_and_picks_equal_one_at_a_time_on_the_shipped_weights(rendered_views, method):
    policy = NetworkPolicy.from_checkpoint(shipped_weights(method), 33, precision="fp32")
    states = random_states(rendered_views, 12, seed=1)  # 72 states, more than MAX_BATCH
    assert len(states) > 2 * MAX_BATCH
    clouds, shown = [c for c, _ in states], [s for _, s in states]
    single = np.stack([policy.predict(c, s) for c, s in states])
    # decide(): the first best unvisited view of predict()
    picks = [int(np.argmax(np.where(s, -np.inf, g))) for s, g in zip(shown, single, strict=True)]
    for k in (5, len(states)):  # uneven batches, and all at once (in chunks of chunk_size)
        batched = np.concatenate(
            [policy.predict_many(clouds[i : i + k], shown[i : i + k]) for i in range(0, 72, k)]
        )
        assert batched.shape == (72, 33) and batched.dtype == np.float32
        gap = float(np.abs(batched - single).max())
        log.info("%s, batches of %d: largest gain difference %.3g", method, k, gap)
        assert gap <= GAIN_TOL
        assert policy.decide_many(clouds, shown) == picks
    # Rounding did not decide the picks: the best unvisited gain leads the second by more.
    masked = np.sort(np.where(np.stack(shown), -np.inf, single), axis=1)
    margin = float((masked[:, -1] - masked[:, -2]).min())
    log.info("%s: smallest lead of a pick over the second best view %.3g", method, margin)
    assert margin > 10 * gap
    assert len(set(picks)) > 5  # the states ask different questions


def test_chunks_hold_at_most_max_points():
    assert chunk_size(512) == 4  # PCNBV's cloud: past 2,048 points a forward leaves the cache
    assert chunk_size(64) == MAX_BATCH  # PCNBV-sph's signature
    assert chunk_size(100_000) == 1


def test_decide_many_masks_the_visited_views_apart_from_the_shown_state(rendered_views):
    policy = NetworkPolicy.from_checkpoint(shipped_weights("pcnbv"), 33, precision="fp32")
    states = random_states(rendered_views[:2], 6, seed=2)
    rng = np.random.default_rng(3)
    shown = [rng.permutation(s) for _, s in states]  # as the permuted_state check shows them
    visited = [s for _, s in states]
    clouds = [c for c, _ in states]
    expected = [policy.decide(c, s, v) for c, s, v in zip(clouds, shown, visited, strict=True)]
    assert policy.decide_many(clouds, shown, visited) == expected
    assert not any(v[p] for v, p in zip(visited, expected, strict=True))


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return nbv.dataset.open(make_tiny_dataset(tmp_path_factory.mktemp("batched") / "data"))


def lockstep(proto, episodes, model, viewspace: str, starts: list[int]) -> list[list[int]]:
    """Episodes from ``starts`` stepped together: one ``choose_many`` a step for all."""
    n = len(model.views[viewspace].poses)
    states = []
    for start in starts:
        state = EpisodeState(model.captured(viewspace), np.zeros(n, dtype=bool), [start])
        state.view_state[start] = True
        states.append(state)
    for _ in range(EPISODE_VIEWS - 1):
        for state, v in zip(states, proto.choose_many(states, episodes), strict=True):
            assert not state.view_state[v]
            state.view_state[v] = True
            state.order.append(v)
    return [state.order for state in states]


@pytest.mark.parametrize("method", ["pcnbv", "pcnbv_sph", "vcnbv", "vcnbv_map"])
@pytest.mark.slow
def test_lockstep_episodes_take_the_views_of_one_at_a_time_episodes(dataset, method):
    """Shipped weights in float32 on whole episodes of the evaluation protocol's start views;
    each episode's own policy records one entry a decision for every stage."""
    model = dataset.model(dataset.keys()[0])
    starts = [1, 3, 7, 10, 15, 24, 27, 30]
    if method.startswith("pcnbv"):
        proto = NetworkPolicy.from_checkpoint(shipped_weights(method), 33, precision="fp32")

        def fresh():
            return proto.fresh()
    else:
        proto = ConditionedPolicy.from_checkpoint(shipped_weights(method))

        def fresh():
            return proto.fresh(InfoGainPolicy(INFOGAIN, dataset.intrinsics))

    alone = [run_episode(model, "original", s, fresh()).views for s in starts]
    episodes = [fresh() for _ in starts]
    assert lockstep(proto, episodes, model, "original", starts) == alone
    stages = {"pcnbv": ["sampling", "network"], "pcnbv_sph": ["signature", "network"],
              "vcnbv": ["sampling", "network"],
              "vcnbv_map": ["map", "sampling", "network"]}  # fmt: skip
    for episode in episodes:
        assert sorted(episode.timings) == sorted(stages[method])
        assert all(len(t) == EPISODE_VIEWS - 1 for t in episode.timings.values())
    assert not proto.timings  # the prototype's own record stays empty


def test_each_episode_keeps_its_own_notes(tmp_path):
    proto = NetworkPolicy.from_checkpoint(save_tiny_checkpoint(tmp_path / "s.pt", "signature"), 33)
    episodes = [proto.fresh() for _ in range(3)]
    rng = np.random.default_rng(0)
    clouds = [rng.normal(size=(40, 3)).astype(np.float32), np.zeros((0, 3), np.float32),
              rng.normal(size=(40, 3)).astype(np.float32)]  # fmt: skip
    states = [np.eye(33, dtype=bool)[i] for i in range(3)]
    alone = [proto.fresh().decide(c, s) for c, s in zip(clouds, states, strict=True)]
    assert proto.decide_many(clouds, states, episodes=episodes) == alone
    assert [len(e.notes) for e in episodes] == [0, 1, 0]
    assert episodes[1].notes[0].startswith(NO_SPREAD)
    # Each episode is charged an equal share of the one forward pass.
    shares = [e.timings["network"][0] for e in episodes]
    assert shares[0] == shares[1] == shares[2] > 0


def test_empty_batches_and_refusals(tmp_path):
    proto = NetworkPolicy.from_checkpoint(save_tiny_checkpoint(tmp_path / "p.pt"), 33)
    other = NetworkPolicy.from_checkpoint(save_tiny_checkpoint(tmp_path / "q.pt", seed=1), 33)
    cloud, state = np.ones((10, 3), np.float32), np.eye(33, dtype=bool)[0]
    assert proto.decide_many([], []) == []
    assert proto.predict_many([], []).shape == (0, 33)
    with pytest.raises(ValueError, match="2 clouds but 1 view states"):
        proto.predict_many([cloud, cloud], [state])
    with pytest.raises(ValueError, match="1 episodes' inputs but 2 episode policies"):
        proto.predict_many([cloud], [state], [proto.fresh(), proto.fresh()])
    with pytest.raises(ValueError, match="episode 1's policy runs another network"):
        proto.predict_many([cloud, cloud], [state, state], [proto.fresh(), other.fresh()])
    with pytest.raises(ValueError, match="no unvisited view"):
        proto.decide_many([cloud], [np.ones(33, dtype=bool)])
    net = ConditionedPolicy.from_checkpoint(
        save_tiny_checkpoint(tmp_path / "m.pt", "directions_map")
    )
    with pytest.raises(ValueError, match="reads each episode's own map"):
        net.view_scores_many([None, None])
    positions = original_viewspace()
    with pytest.raises(ValueError, match=r"hold \[20, 33\] views"):
        ConditionedPolicy.from_checkpoint(save_tiny_checkpoint(tmp_path / "d.pt", "directions")
                                          ).scores_many([cloud, cloud], [positions[:20], positions],
                                                        [state[:20], state])  # fmt: skip
