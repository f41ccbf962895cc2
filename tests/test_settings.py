"""The settings machinery: one frozen dataclass gives the hydra schema, the builder and the
range checks (nbv.config.settings)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from omegaconf import OmegaConf

from nbv.config.schema import ConfigError
from nbv.config.settings import as_config, build, check_ranges, schema, setting
from nbv.utils.fields import at_least, between, one_of, or_null, positive


@dataclass(frozen=True)
class Inner:
    samples: int = setting(8, check=lambda v: v >= 1, allowed="an integer >= 1")
    weights: tuple[float, ...] = (1.0, 2.0)

    def __post_init__(self) -> None:
        check_ranges(self)
        if len(self.weights) > self.samples:
            raise ConfigError(f"weights={list(self.weights)}: more than samples={self.samples}")


@dataclass(frozen=True)
class Camera:
    width: int
    focal: float


@dataclass(frozen=True)
class Outer:
    out_dir: Path
    n_views: int = setting(10, check=lambda v: v >= 2, allowed="an integer >= 2")
    limit: int | None = setting(None, check=lambda v: v is None or v >= 1, allowed="null or >= 1")
    mesh: Path | None = None
    center: tuple[float, float, float] | None = None
    inner: Inner = field(default_factory=Inner)
    named: Inner = setting(factory=lambda: Inner(samples=3), key="other")
    camera: Camera = setting(
        factory=lambda: Camera(640, 500.0),
        config=dict[str, float],
        config_default={"width": 640, "focal": 500.0},
        convert=lambda d: Camera(int(d["width"]), float(d["focal"])),
    )
    per_ring: int | tuple[int, ...] = 8

    def __post_init__(self) -> None:
        check_ranges(self)


def test_schema_has_the_settings_defaults_in_yaml_form():
    node = OmegaConf.structured(schema(Outer))
    assert OmegaConf.to_container(node, throw_on_missing=False)["n_views"] == 10
    assert OmegaConf.is_missing(node, "out_dir")
    assert node.inner.samples == 8 and list(node.inner.weights) == [1.0, 2.0]
    assert node.other.samples == 3
    assert node.camera == {"width": 640, "focal": 500.0}
    assert node.per_ring == 8


def test_build_converts_types_and_nests():
    s = build(Outer, {"out_dir": "runs/a", "center": [0, 1, 2], "inner": {"weights": [3.0]},
                      "per_ring": [4, 6], "camera": {"width": 320, "focal": 200.0}})  # fmt: skip
    assert s == Outer(
        out_dir=Path("runs/a"), center=(0.0, 1.0, 2.0), inner=Inner(weights=(3.0,)),
        per_ring=(4, 6), camera=Camera(320, 200.0),
    )  # fmt: skip
    assert isinstance(s.out_dir, Path) and s.mesh is None
    assert as_config(s)["other"] == {"samples": 3, "weights": [1.0, 2.0]}


@pytest.mark.parametrize(
    ("given", "message"),
    [
        ({"n_views": 1}, "n_views=1: must be an integer >= 2"),
        ({"limit": 0}, "limit=0: must be null or >= 1"),
        ({"inner": {"samples": 0}}, "inner.samples=0: must be an integer >= 1"),
        ({"other": {"samples": 0}}, "other.samples=0: must be an integer >= 1"),
        ({"inner": {"samples": 1}}, "inner.weights=[1.0, 2.0]: more than samples=1"),
        ({"n_views": "many"}, "n_views='many': must be an integer"),
        ({"nope": 1}, "nope: unknown key"),
    ],
)
def test_a_bad_value_names_its_key_path(given, message):
    with pytest.raises(ConfigError) as err:
        build(Outer, {"out_dir": "x", **given})
    assert str(err.value).startswith(message)


def test_missing_required_key_is_named():
    with pytest.raises(ConfigError, match="out_dir: no value"):
        build(Outer, {})


def test_settings_made_in_code_are_checked_alike():
    with pytest.raises(ConfigError, match=r"^n_views=1: must be an integer >= 2$"):
        Outer(out_dir=Path("x"), n_views=1)
    with pytest.raises(ConfigError, match=r"^samples=0: must be an integer >= 1$"):
        Inner(samples=0)


def test_round_trip_through_yaml_form():
    s = Outer(out_dir=Path("o"), center=(1.0, 2.0, 3.0), limit=4)
    assert build(Outer, as_config(s)) == s


@dataclass(frozen=True)
class Deep:
    inner: Inner = setting(factory=lambda: Inner(samples=5))


@dataclass(frozen=True)
class Deeper:
    deep: Deep = field(default_factory=Deep)
    lists: tuple[int, ...] = (1, 2)


def test_a_group_whose_default_holds_a_group_has_a_schema():
    node = OmegaConf.structured(schema(Deeper))
    assert node.deep.inner.samples == 5
    assert build(Deeper, {}) == Deeper()
    assert build(Deeper, {"deep": {"inner": {"samples": 6}}}).deep.inner == Inner(samples=6)
    first, second = schema(Deeper)(), schema(Deeper)()
    first.lists.append(3)
    assert second.lists == [1, 2]  # each instance gets its own copy of a mutable default


@dataclass(frozen=True)
class WithCamera:
    camera: Camera = setting(
        factory=lambda: Camera(640, 500.0),
        config=dict[str, float],
        config_default={"width": 640, "focal": 500.0},
        convert=lambda d: Camera(int(d["width"]), float(d["focal"])),
    )


@dataclass(frozen=True)
class HoldsCameraGroup:
    group: WithCamera = field(default_factory=WithCamera)
    names: tuple[str, ...] = setting((), config=Any, config_default=[], convert=lambda v: named(v))


def named(value):
    if not isinstance(value, list):
        raise ConfigError(f"names={value!r}: must be a list of names")
    return tuple(value)


def test_a_group_default_holding_a_field_with_its_own_yaml_form():
    node = OmegaConf.structured(schema(HoldsCameraGroup))
    assert node.group.camera == {"width": 640, "focal": 500.0}
    assert build(HoldsCameraGroup, {}) == HoldsCameraGroup()


def test_a_converter_message_that_names_its_key_is_not_named_twice():
    with pytest.raises(ConfigError, match=r"^names=5: must be a list of names$"):
        build(HoldsCameraGroup, {"names": 5})


@pytest.mark.parametrize(
    ("allows", "words", "yes", "no"),
    [
        (at_least(1), "an integer >= 1", [1, 7], [0, -3]),
        (at_least(0, "a distance"), "a distance >= 0", [0, 0.5], [-1e-9]),
        (at_least(0, note="0 = all"), "an integer >= 0 (0 = all)", [0, 4], [-1]),
        (positive(), "a positive number", [1e-9, 3], [0, -1]),
        (positive("distance"), "a positive distance", [0.1], [0.0]),
        (between(0, 1), "in [0, 1]", [0, 0.5, 1], [-0.1, 1.1]),
        (between(0.5, 1, "()"), "in (0.5, 1)", [0.6, 0.99], [0.5, 1]),
        (between(0, 0.5, "(]"), "in (0, 0.5]", [0.5, 0.1], [0, 0.6]),
        (between(-90, 90, "[)"), "in [-90, 90)", [-90, 0], [90, -91]),
        (one_of(("a", "b"), " (x=...)"), "one of a, b (x=...)", ["a", "b"], ["c", None]),
        (or_null(at_least(1)), "null or an integer >= 1", [None, 1], [0]),
    ],
)
def test_an_allowed_range_is_declared_once_as_check_and_words(allows, words, yes, no):
    assert allows.words == words
    assert all(allows(v) for v in yes) and not any(allows(v) for v in no)

    @dataclass(frozen=True)
    class One:
        value: Any = setting(yes[0], allows=allows)

        def __post_init__(self) -> None:
            check_ranges(self)

    with pytest.raises(ConfigError, match=rf"^value={no[0]!r}: must be {re.escape(words)}$"):
        One(no[0])


def test_a_setting_takes_allows_or_check_and_allowed_not_both():
    with pytest.raises(TypeError, match="not both"):
        setting(1, allows=at_least(1), check=lambda v: v > 0, allowed="positive")
    with pytest.raises(ValueError, match="closed="):
        between(0, 1, "[[")
