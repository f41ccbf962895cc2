"""Other protocols: generated viewspaces by name, the named protocols of conf/protocol/, the
dataset rendering them, and the evaluator rendering a viewspace a dataset lacks."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from datagen import SMALL_CAMERA, make_tiny_dataset
from tiny_nets import save_tiny_checkpoint

import nbv.dataset
from nbv.dataset.generator import generate
from nbv.dataset.generator_settings import GeneratorSettings, Renderer, Synthetic
from nbv.eval.config import DisturbSettings, EvalConfigError, EvalSettings, PrepareSettings
from nbv.eval.evaluate import evaluate
from nbv.geometry.viewspace import ViewspaceError, elevation, get_viewspace, is_named
from nbv.geometry.viewspace_generators import fibonacci_sphere

ROOT = Path(__file__).resolve().parents[1]


def test_generated_viewspaces_by_name():
    hemi, sphere = get_viewspace("hemisphere_30"), get_viewspace("sphere_32")
    assert hemi.shape == (30, 3) and sphere.shape == (32, 3)
    np.testing.assert_allclose(np.linalg.norm(hemi, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(sphere, axis=1), 1.0, atol=1e-12)
    # The lattice's heights, exactly: 1 - (i + 1/2)/n on the hemisphere, 1 - (2i + 1)/n on the
    # sphere; so every hemisphere view is above the equator and the sphere is symmetric.
    np.testing.assert_allclose(hemi[:, 1], 1 - (np.arange(30) + 0.5) / 30, atol=1e-15)
    np.testing.assert_allclose(sphere[:, 1], 1 - (2 * np.arange(32) + 1) / 32, atol=1e-15)
    assert elevation(hemi).min() > 0 and np.isclose(sphere[:, 1].sum(), 0, atol=1e-12)
    # The names are the rig generator's lattices, Y up, bit for bit.
    np.testing.assert_array_equal(hemi, fibonacci_sphere(30, hemisphere=True))
    np.testing.assert_array_equal(sphere, fibonacci_sphere(32))
    assert is_named("hemisphere_30") and is_named("original") and not is_named("sphere_0")
    with pytest.raises(ViewspaceError, match="'sphere_<n>', 'hemisphere_<n>'"):
        get_viewspace("sphere_x")


def _compose(config: str, overrides: list[str]):
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(str(ROOT / "conf"), version_base="1.3"):
        return compose(config, overrides=overrides)


@pytest.mark.parametrize(("protocol", "n"), [("hemisphere_30", 30), ("sphere_32", 32)])
def test_named_protocols_compose_for_the_evaluation_and_the_dataset(protocol, n):
    from nbv.dataset.config import ENTRY as DATASET
    from nbv.eval.config import ENTRY as EVAL

    ev = EVAL.build(_compose("eval", ["run=x", f"protocol={protocol}"]))
    assert ev.viewspaces == (protocol,) and len(ev.start_views) == 8
    assert max(ev.start_views) < n and len(set(ev.start_views)) == 8
    assert ev.n_views == 10 and ev.prepare.eps == np.sqrt(5e-5)
    ds = DATASET.build(_compose("dataset", [f"protocol={protocol}"]))
    assert ds.viewspaces == {protocol: protocol}
    # The default protocol keeps the datasets made before it: the same identity.
    default = DATASET.build(_compose("dataset", []))
    assert default.data_identity()["viewspaces"] == {"original": "original", "permuted": "permuted"}
    assert "models" not in default.data_identity()


def test_a_viewspace_the_default_start_views_miss_is_refused_naming_the_protocol(tmp_path):
    with pytest.raises(EvalConfigError, match=r"start_views=\[30\].*protocol=hemisphere_30"):
        EvalSettings(run="x", out_root=tmp_path, methods=("spread",), viewspaces=("hemisphere_30",))
    with pytest.raises(EvalConfigError, match="viewspace: unknown 'ring_3'"):
        EvalSettings(run="x", out_root=tmp_path, methods=("spread",), viewspaces=("ring_3",))


@pytest.fixture(scope="module")
def lacking_run(tmp_path_factory):
    """The tiny dataset (original, permuted) evaluated on ``original`` and ``hemisphere_12``,
    which it lacks."""
    tmp = tmp_path_factory.mktemp("protocols")
    data = make_tiny_dataset(tmp / "data")
    settings = EvalSettings(
        run="out",
        out_root=tmp,
        data_dir=data,
        methods=("random", "spread", "oracle", "pcnbv", "vcnbv", "ig"),
        viewspaces=("original", "hemisphere_12"),
        start_views=(1, 5),
        disturb=DisturbSettings(checks=()),
        checkpoints={
            "pcnbv": str(save_tiny_checkpoint(tmp / "pcnbv.pt", "points")),
            "vcnbv": str(save_tiny_checkpoint(tmp / "vcnbv.pt", "directions")),
        },
        prepare=PrepareSettings(dir=tmp / "prepared"),
        random_repeats=2,
        progress=False,
        plots=False,
    )
    return tmp, data, settings, evaluate(settings)


@pytest.mark.slow
def test_the_evaluation_renders_a_lacking_viewspace_as_the_dataset_would(lacking_run):
    tmp, data, settings, evaluation = lacking_run
    (info,) = evaluation.datasets
    assert info.sizes == {"original": 33, "hemisphere_12": 12} and info.rendered is not None
    # Independently: the same models rendered from the hemisphere by a dataset of their own.
    direct = generate(
        GeneratorSettings(
            out_dir=tmp / "direct",
            synthetic=Synthetic(counts={"train": 0, "valid": 0, "test": 0, "unseen": 1}),
            limit=2,
            viewspaces={"hemisphere_12": "hemisphere_12"},
            intrinsics=SMALL_CAMERA,
            n_gt=1000,
            points_per_view=50,
            renderer=Renderer(backend="raycast"),
            progress=False,
        )
    )
    own, rendered = nbv.dataset.open(data), nbv.dataset.open(info.rendered)
    ref = nbv.dataset.open(direct.shard_file)
    assert sorted(rendered.keys()) == sorted(info.keys) == sorted(ref.keys())
    for key in info.keys:
        a, b = rendered.model(key), ref.model(key)
        np.testing.assert_array_equal(a.gt_points, own.model(key).gt_points)
        np.testing.assert_array_equal(a.views["hemisphere_12"].coverage,
                                      b.views["hemisphere_12"].coverage)  # fmt: skip
        np.testing.assert_array_equal(a.views["hemisphere_12"].points,
                                      b.views["hemisphere_12"].points)  # fmt: skip


def test_a_network_tied_to_33_views_is_skipped_there_only(lacking_run):
    *_, evaluation = lacking_run
    assert set(evaluation.skipped) == {"pcnbv on hemisphere_12"}
    assert (
        "33-view viewspace; hemisphere_12 has 12 views"
        in evaluation.skipped["pcnbv on hemisphere_12"]
    )
    ran = {(r.method, r.viewspace) for r in evaluation.records}
    methods = ("random", "spread", "oracle", "pcnbv", "vcnbv", "ig")
    every = {(m, vs) for m in methods for vs in ("original", "hemisphere_12")}
    assert ran == every - {("pcnbv", "hemisphere_12")}
    for r in evaluation.records:
        assert max(r.views) < (12 if r.viewspace == "hemisphere_12" else 33)
        assert len(set(r.views)) == len(r.views) == 10


def test_the_rendered_viewspace_is_cached_and_its_episodes_repeat(lacking_run):
    tmp, _, settings, evaluation = lacking_run
    (info,) = evaluation.datasets
    shard = next(Path(info.rendered).glob("*.h5"))
    before = shard.stat().st_mtime_ns
    again = evaluate(replace(settings, run="again"))
    assert again.datasets[0].rendered == info.rendered
    assert shard.stat().st_mtime_ns == before  # reused, not rendered again
    for a, b in zip(evaluation.records, again.records, strict=True):
        assert (a.method, a.viewspace, a.views) == (b.method, b.viewspace, b.views)
        np.testing.assert_array_equal(a.coverage, b.coverage)
