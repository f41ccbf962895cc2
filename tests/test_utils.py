"""The shared helpers: crash-safe writes, generators derived from names, bit counts, masked argmax,
and the category table."""

import zlib

import numpy as np
import pytest

from nbv.assets.categories import (
    CATEGORIES,
    SHAPENET_CATEGORIES,
    TABLE,
    TRAIN_CATEGORIES,
    UNSEEN_CATEGORIES,
)
from nbv.utils.atomic import append_durably, atomic_path, temporary_name, write_text
from nbv.utils.bits import popcount, popcount_rows
from nbv.utils.seeding import named_rng, seed_sequence, seed_words
from nbv.utils.selection import masked_argmax
from nbv.utils.stats import bootstrap_mean


def test_atomic_path_replaces_only_when_the_body_succeeds(tmp_path):
    target = tmp_path / "sub" / "result.txt"
    write_text(target, "first")
    assert target.read_text() == "first" and not temporary_name(target).exists()
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half of the second")
            raise RuntimeError("killed")
    assert target.read_text() == "first" and not temporary_name(target).exists()
    with atomic_path(target) as tmp:
        assert tmp.parent == target.parent and tmp != target
        tmp.write_text("second")
        assert target.read_text() == "first"  # not replaced before the body ends
    assert target.read_text() == "second"


def test_append_durably_appends(tmp_path):
    log = tmp_path / "log.jsonl"
    append_durably(log, "a\n")
    append_durably(log, "b\nc\n")
    assert log.read_text() == "a\nb\nc\n"


def test_named_generators_hash_strings_with_crc32():
    assert seed_words(3, "chair", 7) == [3, zlib.crc32(b"chair"), 7]
    assert seed_words(0, "é") == [0, zlib.crc32("é".encode())]
    expected = np.random.default_rng(np.random.SeedSequence([5, zlib.crc32(b"a/b"), 2]))
    assert (
        named_rng(5, "a/b", 2).integers(1 << 62, size=8).tolist()
        == expected.integers(1 << 62, size=8).tolist()
    )
    assert seed_sequence(1, "x").entropy == [1, zlib.crc32(b"x")]
    assert named_rng(0, "a").random() != named_rng(0, "b").random()
    assert named_rng(0, "a").random() != named_rng(1, "a").random()


def test_popcount_agrees_with_counting_bits_one_by_one():
    rng = np.random.default_rng(0)
    words = rng.integers(0, 1 << 63, size=(5, 7), dtype=np.uint64) * np.uint64(2) + np.uint64(1)
    words[0, 0] = np.uint64(0xFFFFFFFFFFFFFFFF)
    words[0, 1] = np.uint64(0)
    brute = np.array([[bin(int(w)).count("1") for w in row] for row in words])
    assert np.array_equal(popcount(words), brute)
    assert np.array_equal(popcount_rows(words), brute.sum(axis=1))
    assert words[0, 0] == np.uint64(0xFFFFFFFFFFFFFFFF)  # the input is left as it was
    as_bytes = words.view(np.uint8)
    assert np.array_equal(
        popcount(as_bytes), [[bin(int(b)).count("1") for b in r] for r in as_bytes]
    )
    assert np.array_equal(popcount_rows(as_bytes), brute.sum(axis=1))
    with pytest.raises(TypeError, match="uint8 or uint64"):
        popcount(np.zeros(3, dtype=np.int32))


def test_masked_argmax_skips_visited_views_and_breaks_ties_low():
    values = np.array([5.0, 9.0, 9.0, 1.0])
    assert masked_argmax(values, np.zeros(4, bool)) == 1
    assert masked_argmax(values, np.array([False, True, False, False])) == 2
    assert masked_argmax(values, np.array([True, True, True, False])) == 3
    assert isinstance(masked_argmax(values, np.zeros(4, bool)), int)
    batch = np.array([[1.0, 2.0, 3.0], [3.0, 2.0, 1.0]])
    visited = np.array([[False, False, True], [True, False, False]])
    assert masked_argmax(batch, visited).tolist() == [1, 1]


def test_category_table_is_pc_nbvs():
    assert TRAIN_CATEGORIES == (
        "airplane", "cabinet", "car", "chair", "lamp", "sofa", "table", "vessel",
    )  # fmt: skip
    assert UNSEEN_CATEGORIES == (
        "bus", "bed", "bookshelf", "bench", "guitar", "motorbike", "skateboard", "pistol",
    )  # fmt: skip
    assert CATEGORIES == TRAIN_CATEGORIES + UNSEEN_CATEGORIES
    assert len({c.synset for c in TABLE}) == 16
    assert all(len(c.synset) == 8 and c.synset.isdigit() for c in TABLE)
    assert SHAPENET_CATEGORIES["chair"] == "03001627"


# -- bootstrap intervals --------------------------------------------------------------------------


def test_bootstrap_interval_covers_a_known_mean_at_its_level():
    # 400 samples of 60 draws from N(0.3, 0.1): the 95 % interval covers 0.3 in about 95 % of
    # them (the binomial spread of 400 trials at 0.95 is +-0.011; percentile intervals run a
    # little narrow at n = 60).
    rng = np.random.default_rng(7)
    hits = [
        (iv.low <= 0.3 <= iv.high)
        for iv in (
            bootstrap_mean(rng.normal(0.3, 0.1, 60), seed=i, n_boot=2000) for i in range(400)
        )
    ]
    assert 0.91 <= np.mean(hits) <= 0.98
    one = bootstrap_mean(np.random.default_rng(1).normal(0.3, 0.1, 500))
    assert one.low < 0.3 < one.high and one.mean == pytest.approx(0.3, abs=0.01)


def test_bootstrap_is_seeded_and_resamples_clusters():
    x = np.random.default_rng(0).normal(size=48)
    assert bootstrap_mean(x, seed=3) == bootstrap_mean(x, seed=3)
    assert bootstrap_mean(x, seed=3) != bootstrap_mean(x, seed=4)
    # 6 clusters of 8 identical values: resampling clusters sees 6 values, not 48, so its
    # interval is wider than the one that treats the 48 as independent.
    clustered = np.repeat(np.random.default_rng(1).normal(size=6), 8)
    labels = np.repeat(np.arange(6), 8)
    wide = bootstrap_mean(clustered, labels)
    narrow = bootstrap_mean(clustered)
    assert wide.high - wide.low > 2 * (narrow.high - narrow.low)
    assert wide.clusters == 6 and wide.n == 48
    # With one value per cluster, clusters change nothing.
    assert bootstrap_mean(x, np.arange(48), seed=2) == bootstrap_mean(x, seed=2)
    # A constant difference has a zero-width interval; one cluster has none.
    assert bootstrap_mean(np.full(10, 0.25)).low == pytest.approx(0.25)
    assert np.isnan(bootstrap_mean([1.0, 2.0], ["a", "a"]).low)
    with pytest.raises(ValueError, match="NaN"):
        bootstrap_mean([1.0, np.nan])
    with pytest.raises(ValueError, match="labels"):
        bootstrap_mean([1.0, 2.0], ["a"])
