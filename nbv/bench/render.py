"""Benchmark the depth renderers: seconds a view for Blender and ray casting, in the same run.

:func:`benchmark` renders a 50k-triangle mesh (and every OBJ of a folder) at 640 x 480 from the
original viewspace with both backends, back-projects every view
(:func:`nbv.geometry.camera.backproject`) and checks that the backends agree; the rendering rows
of ``python -m nbv.bench`` come from it, and the developer tool ``scripts/bench_render.py``
prints its whole table. A Blender binary (``blender`` on the PATH by default, e.g. Debian's 3.4.1
from ``scripts/ensure_blender.sh``) gets rows of its own beside the bpy wheel's, named
``<mesh> with the Blender <version> binary``; without one they are skipped with a logged note.

Blender's time a view is measured in steady state: the process first renders one view of the
mesh (start-up, scene set-up), and the clock runs from that mesh's result to the result of the
full set of views, plus the back-projection. Start-up is reported separately.
"""

from __future__ import annotations

import logging
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from nbv.geometry.camera import Intrinsics, backproject, valid_depth, viewspace_poses
from nbv.geometry.viewspace import original_viewspace
from nbv.render.backends import render
from nbv.render.job import RenderError, RenderJob
from nbv.render.preflight import PreflightError, check_blender
from nbv.render.raycast import render_raycast

log = logging.getLogger(__name__)

#: Agreement threshold between the backends, world units.
AGREEMENT_TOL = 1e-4
#: The Blender binary timed beside the bpy wheel by default: the one on the PATH.
DEFAULT_BINARY = "blender"


def bumpy_torus(
    major_sections: int = 200, minor_sections: int = 125, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """A torus (major radius 0.3, minor 0.12) with a smooth random bumpy surface.

    Returns:
        (N, 3) float64 vertices and (2 * major_sections * minor_sections, 3) int64 faces; the
        default is 50,000 triangles inside the unit-diameter sphere.
    """
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 2 * np.pi, major_sections, endpoint=False)
    v = np.linspace(0.0, 2 * np.pi, minor_sections, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    bumps = sum(
        rng.uniform(0.005, 0.015) * np.sin(a * uu + rng.uniform(0, 2 * np.pi))
        * np.cos(b * vv + rng.uniform(0, 2 * np.pi))
        for a, b in ((3, 2), (7, 3), (11, 5))
    )  # fmt: skip
    minor = 0.12 + bumps
    ring = 0.3 + minor * np.cos(vv)
    vertices = np.stack([ring * np.cos(uu), minor * np.sin(vv), ring * np.sin(uu)], axis=-1)
    i, j = np.meshgrid(np.arange(major_sections), np.arange(minor_sections), indexing="ij")
    a = i * minor_sections + j
    b = ((i + 1) % major_sections) * minor_sections + j
    c = ((i + 1) % major_sections) * minor_sections + (j + 1) % minor_sections
    d = i * minor_sections + (j + 1) % minor_sections
    faces = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)]).reshape(-1, 3)
    return vertices.reshape(-1, 3), faces


def agreement(first: np.ndarray, second: np.ndarray, tol: float = AGREEMENT_TOL) -> dict:
    """Compare two depth stacks at the pixels both hit.

    Returns:
        dict with ``common`` (pixels both hit), ``mask_mismatch`` (pixels only one hits),
        ``within`` (fraction of common pixels with |difference| <= tol), ``max`` and ``median``
        absolute difference.
    """
    a, b = valid_depth(first), valid_depth(second)
    both = a & b
    diff = np.abs(first[both].astype(np.float64) - second[both])
    return {
        "common": int(both.sum()),
        "mask_mismatch": int((a != b).sum()),
        "within": float(np.mean(diff <= tol)) if diff.size else float("nan"),
        "max": float(diff.max()) if diff.size else float("nan"),
        "median": float(np.median(diff)) if diff.size else float("nan"),
    }


def _backproject_all(depth: np.ndarray, intrinsics: Intrinsics, poses: np.ndarray) -> int:
    return sum(len(backproject(d, intrinsics, p)) for d, p in zip(depth, poses, strict=True))


def _child_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _time_blender(
    jobs: list[RenderJob], intrinsics: Intrinsics, **kw
) -> tuple[dict[str, float], dict[str, np.ndarray], float]:
    """Render with Blender; returns the arrival time of each key, the depth, and the CPU time of
    the Blender process(es)."""
    arrivals, depth = {}, {}
    cpu = _child_cpu()
    for key, result in render(jobs, intrinsics, "blender", **kw):
        arrivals[key] = time.perf_counter()
        if isinstance(result, RenderError):
            raise result
        depth[key] = result
    return arrivals, depth, _child_cpu() - cpu


def bench_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    threads: int = 2,
    blender: str | None = None,
    workdir: Path | None = None,
) -> dict:
    """Time both backends on one mesh and compare their depth.

    Blender runs twice: once with only a one-view warm-up job (start-up cost), once with the
    warm-up and the full set of views; the difference is the steady-state cost of the views,
    which includes building the mesh in Blender and the EXR round trip. Wall-clock seconds
    depend on what else runs on the machine; CPU seconds much less so.

    Returns:
        dict: seconds a view, wall clock and CPU (``*_s_per_view``, ``*_cpu_s_per_view``) for
        ``blender`` and ``raycast`` rendering, ``backproject``; ``ratio`` (Blender / ray
        casting, rendering alone) and ``ratio_with_backproject``; ``blender_startup_s``;
        ``points`` (back-projected points, all views); ``load`` (1-minute load average at
        the start) and the :func:`agreement` statistics.
    """
    n_views = len(poses)
    load = os.getloadavg()[0]
    kw = {"threads": threads, "blender": blender, "workdir": workdir}
    start = time.perf_counter()
    warm = RenderJob("warmup", vertices, faces, poses[:1])
    _, _, cpu_warmup = _time_blender([warm], intrinsics, **kw)
    startup = time.perf_counter() - start
    full = RenderJob("mesh", vertices, faces, poses)
    arrivals, depth, cpu_both = _time_blender([warm, full], intrinsics, **kw)
    blender_s = (arrivals["mesh"] - arrivals["warmup"]) / n_views
    blender_cpu = (cpu_both - cpu_warmup) / n_views

    render_raycast(vertices, faces, poses[:1], intrinsics, threads=threads)  # loads Open3D
    wall, cpu = time.perf_counter(), time.process_time()
    raycast = render_raycast(vertices, faces, poses, intrinsics, threads=threads)
    raycast_s = (time.perf_counter() - wall) / n_views
    raycast_cpu = (time.process_time() - cpu) / n_views

    wall, cpu = time.perf_counter(), time.process_time()
    points = _backproject_all(depth["mesh"], intrinsics, poses)
    backproject_s = (time.perf_counter() - wall) / n_views
    backproject_cpu = (time.process_time() - cpu) / n_views
    return {
        "views": n_views,
        "triangles": len(faces),
        "load": load,
        "blender_s_per_view": blender_s,
        "blender_cpu_s_per_view": blender_cpu,
        "blender_startup_s": startup,
        "raycast_s_per_view": raycast_s,
        "raycast_cpu_s_per_view": raycast_cpu,
        "backproject_s_per_view": backproject_s,
        "backproject_cpu_s_per_view": backproject_cpu,
        "ratio": blender_s / raycast_s,
        "ratio_with_backproject": (blender_s + backproject_s) / (raycast_s + backproject_s),
        "points": points,
        **agreement(depth["mesh"], raycast),
    }


def _normalised_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    mesh = trimesh.load(path, force="mesh", process=False)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    lo, hi = vertices.min(0), vertices.max(0)
    radius = np.linalg.norm(vertices - (lo + hi) / 2, axis=1).max()
    return (vertices - (lo + hi) / 2) * (0.5 / radius), np.asarray(mesh.faces)


def benchmark(
    n_views: int = 33,
    width: int = 640,
    height: int = 480,
    threads: int = 2,
    meshes_dir: Path | None = None,
    blender: str | None = None,
    repeat: int = 1,
    binary: str | None = DEFAULT_BINARY,
) -> dict:
    """Benchmark both backends on the bumpy torus and optionally on every OBJ in meshes_dir.

    Args:
        n_views: views per mesh, the first n of the original viewspace (cycled beyond 33).
        width, height: image size; the focal length scales with the width (476 px at 640).
        threads: CPU threads for both backends.
        meshes_dir: a folder of .obj files, each normalised into the radius-0.5 sphere.
        blender: a Blender executable, or None for the bpy module.
        repeat: measurements a mesh; the fastest of each time is kept (as ``timeit`` does), which
            filters out other load on a shared machine.
        binary: a Blender binary (path or name on PATH) timed as well, each mesh once more;
            None, or a binary that is missing or fails :func:`~nbv.render.preflight.check_blender`,
            skips it with a logged note.

    Returns:
        ``{mesh name: bench_mesh(...) result}``, and ``{"<mesh name> with the Blender <version>
        binary": ...}`` for the binary.
    """
    if repeat < 1:
        raise ValueError(f"repeat must be >= 1, got {repeat}")
    renderers = {"": blender} | _binary_renderer(binary)
    focal = 476.0 * width / 640.0
    intrinsics = Intrinsics(width, height, focal, focal, (width - 1) / 2, (height - 1) / 2)
    viewspace = original_viewspace()
    poses = viewspace_poses(viewspace[np.arange(n_views) % len(viewspace)])
    meshes = {"bumpy_torus": bumpy_torus()}
    if meshes_dir is not None:
        for path in sorted(Path(meshes_dir).glob("*.obj")):
            meshes[path.stem] = _normalised_obj(path)
    results = {}
    with tempfile.TemporaryDirectory(prefix="nbv-bench-render-") as workdir:
        for name, (vertices, faces) in meshes.items():
            for suffix, executable in renderers.items():
                runs = [
                    bench_mesh(
                        vertices, faces, poses, intrinsics, threads, executable, Path(workdir)
                    )
                    for _ in range(repeat)
                ]
                results[name + suffix] = _fastest(runs)
    return results


def _binary_renderer(binary: str | None) -> dict[str, str]:
    """``{" with the Blender <version> binary": path}`` when ``binary`` passes the preflight
    check, else ``{}`` with a logged note saying why it is skipped."""
    if binary is None:
        return {}
    path = shutil.which(binary)
    if path is None:
        log.warning(
            "no Blender binary %r (not an executable, nor a command on the PATH): its rows are "
            "skipped (Debian/Ubuntu: bash scripts/ensure_blender.sh; elsewhere put a Blender "
            "3.4-5.0 on the PATH or give --binary PATH)",
            binary,
        )
        return {}
    try:
        info = check_blender(path)
    except PreflightError as err:
        log.warning("the Blender binary's rows are skipped: %s", err)
        return {}
    return {f" with the Blender {'.'.join(map(str, info.version))} binary": path}


def _fastest(runs: list[dict]) -> dict:
    """Combine repeated bench_mesh results: the minimum of every time, the highest load."""
    best = dict(runs[-1])
    for key in best:
        if key.endswith(("_s_per_view", "_startup_s")):
            best[key] = min(run[key] for run in runs)
    best["load"] = max(run["load"] for run in runs)
    blender, raycast, bp = (best[f"{k}_s_per_view"] for k in ("blender", "raycast", "backproject"))
    best["ratio"] = blender / raycast
    best["ratio_with_backproject"] = (blender + bp) / (raycast + bp)
    return best


def format_table(results: dict) -> str:
    """The benchmark results as a fixed-width text table (seconds a view: wall / CPU)."""
    width = max([12, *(len(name) + 1 for name in results)])
    head = (
        f"{'mesh':<{width}}{'tris':>7}{'views':>6}{'blender s':>16}{'raycast s':>16}"
        f"{'backproj s':>16}{'ratio':>7}{'+bp':>6}{'start s':>8}{'<=1e-4':>9}"
        f"{'mask diff':>10}{'load':>6}"
    )
    rows = [head, "-" * len(head)]
    for name, r in results.items():
        pairs = [
            f"{r[k + '_s_per_view']:.4f}/{r[k + '_cpu_s_per_view']:.4f}"
            for k in ("blender", "raycast", "backproject")
        ]
        rows.append(
            f"{name:<{width}}{r['triangles']:>7}{r['views']:>6}{pairs[0]:>16}{pairs[1]:>16}"
            f"{pairs[2]:>16}{r['ratio']:>7.1f}{r['ratio_with_backproject']:>6.1f}"
            f"{r['blender_startup_s']:>8.2f}{r['within']:>9.5f}{r['mask_mismatch']:>10d}"
            f"{r['load']:>6.1f}"
        )
    rows.append(
        "seconds a view as wall/CPU; ratio = Blender / ray casting (+bp: with back-projection)"
    )
    return "\n".join(rows)
