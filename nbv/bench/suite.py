"""The benchmark suite of ``python -m nbv.bench`` (``make bench``; the command is
:mod:`nbv.bench.__main__`, its settings ``conf/bench.yaml``): one table of the fast paths against
plain references.

Every row times the project's implementation and an independent, plain implementation of the same
thing on the same data in the same run, and gives the ratio. The data: a synthetic chair rendered
by ray casting from the 33 original views at 640 x 480 (full-resolution view clouds), its
16384-point ground truth, and a 100k-point cloud from its views. A PCNBV inference episode on those
views follows, and a training step of each network beside its FLOP floor (``network=false`` skips
them; trained weights from ``checkpoint=...``, by default fold 0's ``best.pt`` when it exists),
and the last rows compare the two rendering backends (``render=false`` skips them).

Targets (issues 3, 4 and 5) are printed beside the measured times; the paper's are in FACTS.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, cKDTree

from nbv.assets.meshes import Mesh, normalise, sample_surface
from nbv.assets.synthetic import build, catalogue
from nbv.assets.weights import SHIPPED_SCORER
from nbv.bench.infogain import decision_row
from nbv.bench.plan import capture_rows
from nbv.bench.timing import best_time
from nbv.bench.warm import warm_rows
from nbv.geometry.camera import Intrinsics, backproject, viewspace_poses
from nbv.geometry.clouds import farthest_points
from nbv.geometry.hull import hull_volume
from nbv.geometry.scores import (
    DEFAULT_EPS,
    DEFAULT_N_GT,
    coverage_bits,
    coverage_from_bits,
    view_hull_vertices,
    vig_of_state,
)
from nbv.geometry.sph import equiangular_directions, signature, unit_vectors
from nbv.geometry.union import UnionHulls
from nbv.geometry.viewspace import original_viewspace
from nbv.infogain.gain_scorer import load_scorer
from nbv.policies.registry import PCNBV, PCNBV_SPH
from nbv.render.raycast import render_raycast
from nbv.scan.shipped import resolve_weights
from nbv.setcover.greedy import greedy_max_coverage
from nbv.setcover.hull_sampling import DEFAULT_N_SAMP, convex_hull, sample_hull
from nbv.setcover.oneshot import Plan
from nbv.setcover.oneshot import plan as sco_plan
from nbv.setcover.settings import SetCoverSettings
from nbv.setcover.view_sets import view_sets

#: Points of the small ground truth whose hull :func:`small_gt_hull_error` checks.
SMALL_GT = 512


def numpy_fps(points: np.ndarray, n: int, start: int = 0) -> np.ndarray:
    """Reference farthest point sampling: plain numpy, O(N n), started at point ``start``."""
    chosen = np.full(n, start, dtype=np.int64)
    dist = np.full(len(points), np.inf)
    for i in range(1, n):
        dist = np.minimum(dist, ((points - points[chosen[i - 1]]) ** 2).sum(axis=1))
        chosen[i] = int(np.argmax(dist))
    return points[chosen]


def scipy_signature(points: np.ndarray, lmax: int) -> np.ndarray:
    """Reference signature: scipy's complex harmonics made real, ``lstsq``, then evaluation."""
    from scipy.special import sph_harm_y

    def design(theta, phi):
        cols = []
        for l in range(lmax + 1):  # noqa: E741
            for m in range(-l, l + 1):
                y = sph_harm_y(l, abs(m), theta, phi)
                sign = (-1.0) ** m
                if m > 0:
                    cols.append(np.sqrt(2) * sign * y.real)
                elif m < 0:
                    cols.append(np.sqrt(2) * sign * y.imag)
                else:
                    cols.append(y.real)
        return np.stack(cols, axis=-1)

    centred = points - points.mean(axis=0)
    r = np.linalg.norm(centred, axis=1)
    theta = np.arccos(np.clip(centred[:, 2] / r, -1, 1))
    phi = np.arctan2(centred[:, 1], centred[:, 0])
    coeffs = np.linalg.lstsq(design(theta, phi), r, rcond=None)[0]
    grid_theta, grid_phi = equiangular_directions(lmax)
    radius = design(grid_theta, grid_phi) @ coeffs
    return radius[:, None] * unit_vectors(grid_theta, grid_phi)


def python_greedy(sets: np.ndarray, n_iter: int, exclude: tuple[int, ...]) -> list[int]:
    """Reference greedy maximum coverage over Python sets (Algorithm 3)."""
    elements = [set(np.flatnonzero(row).tolist()) for row in sets]
    covered = set().union(*(elements[v] for v in exclude))
    chosen = []
    for _ in range(n_iter):
        free = [v for v in range(len(elements)) if v not in chosen and v not in exclude]
        best = max(free, key=lambda v: (len(elements[v] - covered), -v))
        chosen.append(best)
        covered |= elements[best]
    return chosen


def rng_pick(n: int, k: int, seed: int) -> np.ndarray:
    """Sorted random subset of ``k`` of ``range(n)`` (all when ``k >= n``)."""
    if k >= n:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, k, replace=False))


def bench_scene(seed: int = 0) -> dict:
    """The benchmark's data: full-resolution views of a synthetic chair and its ground truth."""
    rng = np.random.default_rng(seed)
    entry = next(e for e in catalogue() if e.category == "chair")
    vertices, faces = build(entry, seed)
    mesh, _, _ = normalise(Mesh(vertices, faces))
    intrinsics = Intrinsics.centred()
    poses = viewspace_poses(original_viewspace())
    depth = render_raycast(mesh.vertices, mesh.faces, poses, intrinsics)
    views = [backproject(d, intrinsics, p) for d, p in zip(depth, poses, strict=True)]
    merged = np.concatenate(views)
    cloud = merged[rng.choice(len(merged), min(100_000, len(merged)), replace=False)]
    return {
        "mesh": mesh,
        "views": views,
        "gt": sample_surface(mesh, DEFAULT_N_GT, rng).astype(np.float64),
        "cloud100k": cloud,
        "poses": poses,
        "intrinsics": intrinsics,
    }


def _timed(name: str, ours, reference, target: float | None, note: str = "") -> dict:
    """A row: ``ours`` timed against ``reference``, a callable to time or the seconds an earlier
    row measured for it."""
    t_ours = best_time(ours)
    t_ref = reference if isinstance(reference, float) else best_time(reference, repeat=2, budget=10)
    return dict(name=name, ours=t_ours, reference=t_ref, ratio=t_ref / t_ours, target=target,
                note=note)  # fmt: skip


def _geometry_rows(scene: dict) -> list[dict]:
    """Sampling, signatures, and the coverage and VIG of a view state and of an episode."""
    views, gt, cloud = scene["views"], scene["gt"], scene["cloud100k"]
    state = np.zeros(33, dtype=bool)
    state[[1, 9, 17, 20, 28]] = True
    bits = coverage_bits(views, gt, DEFAULT_EPS)
    hulls = view_hull_vertices(views)
    gt_vol = hull_volume(gt)
    merged_state = np.concatenate([views[v] for v in np.flatnonzero(state)])
    episode = [1, 3, 7, 10, 15, 24, 27, 30, 0, 5]

    def union_curve() -> list[float]:
        unions = UnionHulls(hulls)  # one memo for the episode, as a model record holds it
        return [unions.volume(episode[:i]) / gt_vol for i in range(1, 11)]

    def per_view_curve() -> float:
        return [vig_of_state(hulls, np.isin(np.arange(33), episode[:i]), gt_vol)
                for i in range(1, 11)][-1]  # fmt: skip

    return [
        _timed("farthest point sampling 100k -> 1024", lambda: farthest_points(cloud, 1024),
               lambda: numpy_fps(cloud, 1024), 0.030, "fpsample vs numpy"),
        _timed("signature 100k points, lmax 3", lambda: signature(cloud, 3),
               lambda: scipy_signature(cloud, 3), 0.020, "recurrences vs scipy+lstsq"),
        _timed("signature 100k points, lmax 10", lambda: signature(cloud, 10),
               lambda: scipy_signature(cloud, 10), None, "recurrences vs scipy+lstsq"),
        _timed("coverage of a view state (5 views)",
               lambda: coverage_from_bits(bits, state, len(gt)),
               lambda: (cKDTree(merged_state).query(gt)[0] < DEFAULT_EPS).mean(), 50e-6,
               "packed bits vs KD-tree on merged cloud"),
        _timed("VIG of a view state (5 views)", lambda: vig_of_state(hulls, state, gt_vol),
               lambda: ConvexHull(merged_state).volume / gt_vol, 0.002,
               "per-view hull vertices vs hull of merged cloud"),
        _timed("VIG curve of a 10-view episode", union_curve, per_view_curve, None,
               "unions grown from the last hull vs per-view vertices each step"),
    ]  # fmt: skip


def _set_cover_rows(scene: dict, start_cloud: np.ndarray, seed: int) -> list[dict]:
    """The set cover's stages and whole plans from a stored start view."""
    start_hull = start_cloud[ConvexHull(start_cloud).vertices]
    samples, normals, face_ids = sample_hull(
        start_hull, DEFAULT_N_SAMP, np.random.default_rng(seed)
    )
    hull = convex_hull(start_hull)
    poses, intrinsics = scene["poses"], scene["intrinsics"]
    sets = view_sets(samples, normals, poses, intrinsics)

    def plan(**kw) -> Plan:
        return sco_plan(start_cloud, original_viewspace(), exclude=(1,),
                        settings=SetCoverSettings(**kw), poses=poses)  # fmt: skip

    rows = [
        _timed("view simulation, 33 views on a hull",
               lambda: view_sets(samples, normals, poses, intrinsics, face_ids=face_ids),
               lambda: view_sets(samples, normals, poses, intrinsics, method="raycast", hull=hull),
               None, "analytic vs ray casting"),
        _timed("greedy set cover, 9 of 33 views", lambda: greedy_max_coverage(sets, 9, (1,)),
               lambda: python_greedy(sets, 9, (1,)), 0.001, "packed bits vs Python sets"),
        _timed("whole 9-view plan (hull+sim+sets+greedy), 2048-point start view", plan,
               lambda: plan(simulation="raycast"), 0.050, "analytic vs ray-cast simulation"),
    ]  # fmt: skip
    # The same ray-cast plan as the row above is the reference.
    rows.append(
        _timed(
            "whole 9-view plan with eps-dilated sets",
            lambda: plan(dilate=True),
            rows[-1]["reference"],
            0.050,
            "dilated analytic vs ray-cast simulation",
        )
    )
    return rows


def _render_rows(scene: dict) -> list[dict]:
    """Rendering and back-projecting a view: ray casting against Blender."""
    import tempfile

    import trimesh

    from nbv.bench.render import benchmark

    with tempfile.TemporaryDirectory() as folder:
        # The dataset's meshes are small: time a synthetic chair too, beside the 50k torus.
        trimesh.Trimesh(scene["mesh"].vertices, scene["mesh"].faces).export(
            Path(folder) / "synthetic_chair.obj"
        )
        results = benchmark(n_views=12, meshes_dir=Path(folder))
    rows = []
    for name, r in results.items():
        blender = r["blender_s_per_view"] + r["backproject_s_per_view"]
        raycast = r["raycast_s_per_view"] + r["backproject_s_per_view"]
        rows.append(dict(
            name=f"render + back-project a 640x480 view, {name} ({r['triangles']} tri.)",
            ours=raycast, reference=blender, ratio=blender / raycast, target=0.25,
            note="ray casting vs Blender; the target is Blender's",
        ))  # fmt: skip
    return rows


def run(
    render: bool = True,
    network: bool = True,
    checkpoint: Path | None = None,
    seed: int = 0,
) -> list[dict]:
    """Measure every row; returns dicts with name, ours, reference, ratio, target (seconds).

    ``network`` adds the network rows of :func:`nbv.bench.network.network_rows` and the
    training rows of :func:`nbv.bench.training.training_rows` (PCNBV's weights from
    ``checkpoint``, else the shipped ones; PCNBV-sph's shipped) and the completion rows of
    :func:`nbv.bench.completion.completion_rows`;
    ``render`` the rendering rows."""
    scene = bench_scene(seed)
    views = scene["views"]
    # The planner sees a start view as the dataset stores it (points_per_view = 2048).
    start_cloud = views[1][rng_pick(len(views[1]), 2048, seed)]
    rows = _geometry_rows(scene) + _set_cover_rows(scene, start_cloud, seed)
    # The views as the dataset stores them (points_per_view = 2048).
    stored = [v[rng_pick(len(v), 2048, seed + i)] for i, v in enumerate(views)]
    rows.append(decision_row(stored, scene["poses"], scene["intrinsics"]))
    rows.append(
        decision_row(stored, scene["poses"], scene["intrinsics"], load_scorer(SHIPPED_SCORER))
    )
    rows += capture_rows(views, scene["poses"], scene["intrinsics"])
    rows += warm_rows()
    if network:
        from nbv.bench.network import network_rows
        from nbv.bench.training import training_rows

        pcnbv = checkpoint if checkpoint is not None else resolve_weights(PCNBV.name, None)
        networks = [("PCNBV", pcnbv), ("PCNBV-sph", resolve_weights(PCNBV_SPH.name, None))]
        targets = {"PCNBV": 0.13, "PCNBV-sph": 0.04}
        rows += network_rows(stored, [(name, w, targets[name]) for name, w in networks])
        rows += training_rows(networks, len(stored))
        from nbv.bench.completion import completion_rows

        rows += completion_rows(stored, scene["poses"], scene["intrinsics"])
    if render:
        rows += _render_rows(scene)
    return rows


def small_gt_hull_error(dataset_dir: Path, n: int = SMALL_GT, seed: int = 0) -> dict:
    """The paper's claim that an ``n``-point ground truth has nearly the hull volume of the
    full one (:data:`~nbv.geometry.scores.DEFAULT_N_GT` points).

    For every model with a hull volume: relative shortfall ``(V_full - V_n) / V_full`` of the hull
    of a seeded random ``n``-point subset of the ground truth.

    Returns:
        ``{"models", "mean", "median", "worst"}`` of the relative shortfall.
    """
    from nbv.dataset import open_dataset

    dataset = open_dataset(dataset_dir)
    rng = np.random.default_rng(seed)
    shortfall = []
    for key in dataset:
        gt = dataset.model(key, ()).gt_points
        full = hull_volume(gt)
        if full > 0:
            shortfall.append((full - hull_volume(gt[rng.choice(len(gt), n, replace=False)])) / full)
    values = np.array(shortfall)
    return {
        "models": len(values),
        "mean": float(values.mean()),
        "median": float(np.median(values)),
        "worst": float(values.max()),
    }


def format_table(rows: list[dict]) -> str:
    """Markdown table of :func:`run`'s rows, times in milliseconds."""
    lines = [
        "| what | ours (ms) | reference (ms) | speed-up | target (ms) | met | compared |",
        "|---|---:|---:|---:|---:|:-:|---|",
    ]
    for r in rows:
        target = "" if r["target"] is None else f"{r['target'] * 1e3:g}"
        checked = r["reference"] if r["name"].startswith("render") else r["ours"]
        met = "" if r["target"] is None else ("yes" if checked <= r["target"] else "NO")
        lines.append(
            f"| {r['name']} | {r['ours'] * 1e3:.3f} | {r['reference'] * 1e3:.1f} | "
            f"{r['ratio']:.1f}x | {target} | {met} | {r['note']} |"
        )
    return "\n".join(lines)
