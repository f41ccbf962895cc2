"""Depth renderers: ray casting against brute force and the analytic sphere; Blender against it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import trimesh

from nbv.geometry.camera import (
    Intrinsics,
    look_at,
    opencv_to_blender,
    pixel_rays,
    valid_depth,
    viewspace_poses,
)
from nbv.geometry.viewspace import original_viewspace
from nbv.render.backends import render
from nbv.render.blender import (
    BLENDER_SCRIPT,
    cpu_shares,
    remove_orphans,
    render_blender,
    scratch_folder,
)
from nbv.render.job import RenderError, RenderJob
from nbv.render.noise import DepthNoise, incidence_angles, noisy_depth
from nbv.render.raycast import render_raycast

CAMERA = Intrinsics.centred(80, 60, 60.0)
#: Off-centre principal point and non-square pixels.
ODD_CAMERA = Intrinsics(80, 60, 60.0, 66.0, 45.25, 26.5)
SPHERE_RADIUS = 0.4


def _poses(*eyes) -> np.ndarray:
    return np.stack([look_at(np.asarray(e, dtype=float)) for e in eyes])


#: Pole view (0, 1, 0), two oblique views and one from below the equator, all at distance 1.
POSES = _poses([0, 1, 0], [0, 0, 1], [0.55, 0.5, 0.67], [-0.8, -0.45, 0.4])


def _sphere() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=5, radius=SPHERE_RADIUS)


def _box_at_x() -> trimesh.Trimesh:
    box = trimesh.creation.box((0.2, 0.3, 0.25))
    box.apply_translation([0.3, 0.0, 0.0])
    return box


def _two_parts(major: int = 48, minor: int = 24) -> trimesh.Trimesh:
    """A torus and a box beside it: two components, with a hole."""
    torus = trimesh.creation.torus(0.25, 0.08, major_sections=major, minor_sections=minor)
    box = trimesh.creation.box((0.15, 0.15, 0.15))
    box.apply_translation([0.0, 0.25, 0.1])
    return trimesh.util.concatenate([torus, box])


def _brute_force_depth(mesh: trimesh.Trimesh, pose: np.ndarray, k: Intrinsics) -> np.ndarray:
    """Möller-Trumbore against every triangle, float64: (H, W) planar depth, inf background."""
    rays = pixel_rays(k).reshape(-1, 3) @ pose[:3, :3].T
    tri = np.asarray(mesh.triangles)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(rays[:, None], e2[None])
    det = np.einsum("tk,rtk->rt", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = pose[:3, 3] - tri[:, 0]
        u = np.einsum("tk,rtk->rt", s, p) / det
        q = np.cross(s, e1)
        v = np.einsum("rk,tk->rt", rays, q) / det
        t = np.einsum("tk,tk->t", e2, q)[None] / det
    hit = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return np.where(hit, t, np.inf).min(axis=1).reshape(k.height, k.width)


def _analytic_sphere(pose: np.ndarray, k: Intrinsics, radius: float) -> tuple[np.ndarray, ...]:
    """Planar depth of a true sphere at the origin, the ray's distance to the centre, and the
    cosine of the incidence angle: three (H, W) arrays (depth inf where the ray misses)."""
    rays = pixel_rays(k) @ pose[:3, :3].T
    c = pose[:3, 3]
    a = np.einsum("hwk,hwk->hw", rays, rays)
    b = rays @ c
    closest = np.sqrt(np.maximum(c @ c - b**2 / a, 0.0))
    disc = b**2 - a * (c @ c - radius**2)
    with np.errstate(invalid="ignore"):
        t = (-b - np.sqrt(disc)) / a
        normal = (c + t[..., None] * rays) / radius
        cosine = -np.einsum("hwk,hwk->hw", normal, rays) / np.sqrt(a)
    return np.where(disc > 0, t, np.inf), closest, cosine


def _check_sphere(depth: np.ndarray, pose: np.ndarray, k: Intrinsics, tol: float) -> None:
    """The icosphere lies inside the true sphere, at least ``inner`` from the centre: its depth
    is the analytic one plus at most gap / cos(incidence), and its silhouette sits in the disc."""
    mesh = _sphere()
    inner = np.abs(np.einsum("fk,fk->f", mesh.face_normals, mesh.triangles[:, 0])).min()
    gap = SPHERE_RADIUS - inner
    analytic, closest, cosine = _analytic_sphere(pose, k, SPHERE_RADIUS)
    hit = valid_depth(depth)
    assert not np.any(hit & ~np.isfinite(analytic)), "mesh hit outside the analytic disc"
    assert np.all(closest[np.isfinite(analytic) & ~hit] >= inner - 1e-9), "hole inside the disc"
    face_on = hit & (cosine > 0.3)
    assert face_on.sum() > 0.5 * hit.sum()
    excess = depth[face_on] - analytic[face_on]
    assert excess.min() >= -tol
    assert np.all(excess <= gap / cosine[face_on] + tol)


def _agreement(first: np.ndarray, second: np.ndarray) -> tuple[float, float]:
    """Fraction of common hit pixels within 1e-4, and the fraction of pixels only one hits."""
    a, b = valid_depth(first), valid_depth(second)
    both = a & b
    assert both.sum() > 0
    return float(np.mean(np.abs(first[both] - second[both]) <= 1e-4)), float(np.mean(a != b))


# ---------------------------------------------------------------------------------------------
# Ray casting


@pytest.mark.parametrize("k", [CAMERA, ODD_CAMERA], ids=["centred", "off-centre"])
@pytest.mark.parametrize(
    "make", [_box_at_x, lambda: _two_parts(16, 8)], ids=["box", "coarse-two-parts"]
)
def test_raycast_matches_brute_force(make, k):
    mesh = make()
    depth = render_raycast(mesh.vertices, mesh.faces, POSES, k)
    assert depth.shape == (len(POSES), k.height, k.width) and depth.dtype == np.float32
    for d, pose in zip(depth, POSES, strict=True):
        expected = _brute_force_depth(mesh, pose, k)
        hit = np.isfinite(expected)
        # Only rays grazing an edge may disagree on hit or miss.
        assert np.mean(np.isfinite(d) != hit) < 0.002
        both = hit & np.isfinite(d)
        np.testing.assert_allclose(d[both], expected[both], rtol=0, atol=2e-6)
        assert np.all(np.isinf(d[~valid_depth(d)]))


@pytest.mark.parametrize("k", [CAMERA, ODD_CAMERA], ids=["centred", "off-centre"])
def test_raycast_sphere_is_analytic(k):
    mesh = _sphere()
    depth = render_raycast(mesh.vertices, mesh.faces, POSES, k)
    for d, pose in zip(depth, POSES, strict=True):
        _check_sphere(d, pose, k, tol=1e-6)


def test_raycast_orientation():
    """A box at +x seen from +z (world up +y) is on the right, one at +y is at the top."""
    pose = _poses([0, 0, 1])
    right = render_raycast(_box_at_x().vertices, _box_at_x().faces, pose, CAMERA)[0]
    cols = np.nonzero(valid_depth(right))[1]
    assert cols.size and cols.min() > CAMERA.cx
    up = trimesh.creation.box((0.2, 0.2, 0.2))
    up.apply_translation([0.0, 0.3, 0.0])
    rows = np.nonzero(valid_depth(render_raycast(up.vertices, up.faces, pose, CAMERA)[0]))[0]
    assert rows.size and rows.max() < CAMERA.cy


def test_render_raycast_stream_reports_bad_meshes():
    box = _box_at_x()
    jobs = [
        RenderJob("good", box.vertices, box.faces, POSES[:2]),
        RenderJob("bad", box.vertices, box.faces + 100, POSES[:2]),
        RenderJob("flat", box.vertices[:, :2], box.faces, POSES[:2]),
    ]
    results = dict(render(jobs, CAMERA, backend="raycast"))
    assert list(results) == ["good", "bad", "flat"]
    np.testing.assert_array_equal(
        results["good"], render_raycast(box.vertices, box.faces, POSES[:2], CAMERA)
    )
    assert isinstance(results["bad"], RenderError) and "face indices" in str(results["bad"])
    assert isinstance(results["flat"], RenderError) and "'flat'" in str(results["flat"])


def test_render_refuses_bad_settings(tmp_path):
    with pytest.raises(ValueError, match="blender.*raycast"):
        render([], CAMERA, backend="eevee")
    with pytest.raises(ValueError, match="device"):
        render([], CAMERA, backend="raycast", device="GPU")
    with pytest.raises(ValueError, match="device must be one of"):
        render_blender([], CAMERA, tmp_path, device="TPU")
    with pytest.raises(ValueError, match="threads"):
        render([], CAMERA, threads=-1)
    with pytest.raises(FileNotFoundError, match="no-such-blender"):
        render_blender([], CAMERA, tmp_path, blender="/no-such-blender")
    with pytest.raises(ValueError, match="processes must be an integer >= 1"):
        render_blender([], CAMERA, tmp_path, processes=0)
    with pytest.raises(ValueError, match="takes options"):
        render([], CAMERA, backend="raycast", processes=2)


# ---------------------------------------------------------------------------------------------
# Blender


def _children() -> list[int]:
    """Process ids of this process's live (not zombie) children (Linux /proc)."""
    me, found = os.getpid(), []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            state, parent = stat.rsplit(")", 1)[1].split()[:2]
            if int(parent) == me and state != "Z":
                found.append(int(entry))
    return found


@pytest.mark.blender
@pytest.mark.slow
def test_blender_agrees_with_raycast_and_streams(tmp_path):
    """One process renders several meshes and views, yielding each mesh as soon as it is done;
    an invalid job is reported without stopping the others; nothing is left in workdir."""
    meshes = {"sphere": _sphere(), "box": _box_at_x(), "parts": _two_parts()}
    jobs = [RenderJob(key, m.vertices, m.faces, POSES) for key, m in meshes.items()]
    jobs.insert(1, RenderJob("broken", np.zeros((3, 3)), np.array([[0, 1, 5]]), POSES))
    odd = RenderJob("parts-odd-camera", meshes["parts"].vertices, meshes["parts"].faces, POSES)

    results, alive_at_first_result = {}, None
    others = set(_children())  # not the renderer's (see test_blender_crash_restarts_for_the_rest)
    for key, result in render(jobs, CAMERA, workdir=tmp_path, threads=2):
        if alive_at_first_result is None and not isinstance(result, RenderError):
            alive_at_first_result = bool(set(_children()) - others)
        results[key] = result
    assert alive_at_first_result, "the first mesh should arrive while Blender still renders"
    assert list(results) == ["broken", "sphere", "box", "parts"]
    assert isinstance(results["broken"], RenderError) and "face indices" in str(results["broken"])
    assert not any(tmp_path.iterdir())

    # Without a workdir a temporary one is made and removed.
    before = set(Path(tempfile.gettempdir()).glob("nbv-blender-*"))
    ((_, odd_depth),) = render([odd], ODD_CAMERA)
    assert set(Path(tempfile.gettempdir()).glob("nbv-blender-*")) <= before
    results["parts-odd-camera"] = odd_depth
    for key, depth in results.items():
        if key == "broken":
            continue
        k = ODD_CAMERA if key == "parts-odd-camera" else CAMERA
        mesh = meshes[key.split("-")[0]]
        assert depth.shape == (len(POSES), k.height, k.width) and depth.dtype == np.float32
        reference = render_raycast(mesh.vertices, mesh.faces, POSES, k)
        for v in range(len(POSES)):
            within, mask_mismatch = _agreement(depth[v], reference[v])
            assert within >= 0.99, (key, v, within)
            assert mask_mismatch <= 0.005, (key, v, mask_mismatch)
        assert np.all(np.isinf(depth[~valid_depth(depth)]))
    for d, pose in zip(results["sphere"], POSES, strict=True):
        _check_sphere(d, pose, CAMERA, tol=1e-4)
    # Orientation: the box at +x is on the right of the view from +z (pose 1).
    cols = np.nonzero(valid_depth(results["box"][1]))[1]
    assert cols.size and cols.min() > CAMERA.cx


@pytest.mark.blender
@pytest.mark.slow
def test_blender_processes_render_the_same_depth(tmp_path):
    """Two Blender processes of one thread, each replaced after every mesh (chunk=1), give
    every mesh the depth of one process of two threads, bit for bit; a key given twice is
    refused even when the two land in different processes; nothing is left in workdir."""
    meshes = {"sphere": _sphere(), "box": _box_at_x(), "parts": _two_parts()}
    jobs = [RenderJob(key, m.vertices, m.faces, POSES) for key, m in meshes.items()]
    jobs.append(RenderJob("box", meshes["box"].vertices, meshes["box"].faces, POSES))
    one = dict(render(jobs[:3], CAMERA, workdir=tmp_path, threads=2))
    results = list(render(jobs, CAMERA, workdir=tmp_path, threads=1, processes=2, chunk=1))
    assert sorted(k for k, _ in results) == ["box", "box", "parts", "sphere"]
    refused = [r for k, r in results if isinstance(r, RenderError)]
    assert len(refused) == 1 and "duplicate key" in str(refused[0])
    two = {k: r for k, r in results if not isinstance(r, RenderError)}
    assert two.keys() == one.keys()
    for key, depth in one.items():
        assert np.array_equal(two[key], depth), key
    assert not any(tmp_path.iterdir())


def test_cpu_shares_bind_each_process_to_its_own_cpus():
    assert cpu_shares([0, 1], 2) == [[0], [1]]
    assert cpu_shares([0, 1, 2, 3, 4], 2) == [[0, 2, 4], [1, 3]]
    assert cpu_shares([3, 5], 3) == [[3], [5], [3]]  # more processes than CPUs: in turn
    assert cpu_shares([7], 1) == [[7]]


def test_scratch_folder_is_in_ram_only_with_room(tmp_path):
    ram, work = tmp_path / "ram", tmp_path / "work"
    ram.mkdir(), work.mkdir()
    assert scratch_folder(work, 1, ram=ram).parent == ram
    assert scratch_folder(work, 1 << 60, ram=ram).parent == work  # no room for 16 images
    assert scratch_folder(work, 1, ram=tmp_path / "absent").parent == work
    assert scratch_folder(work, 1, ram=ram).name.startswith(f"nbv-exr-{os.getpid()}-")


def test_scratch_folders_of_dead_processes_are_removed_once_old(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # reaped: its id names no process now
    hour_ago = time.time() - 3700

    def folder(name: str, age: float | None = hour_ago) -> Path:
        path = tmp_path / name
        (path / "nbv-exr-inner").mkdir(parents=True)
        exr = path / "nbv-exr-inner" / "depth.exr"
        exr.write_bytes(b"x")
        if age is not None:
            for p in (exr, exr.parent, path):
                os.utime(p, (age, age))
        return path

    orphan = folder(f"nbv-exr-{dead.pid}-abc")
    fresh = folder(f"nbv-exr-{dead.pid}-def", age=None)  # its process may be in another namespace
    mine = folder(f"nbv-exr-{os.getpid()}-ghi")
    old_form = folder("nbv-exr-jkl")  # no process id in the name
    other = folder(f"other-{dead.pid}-mno")
    assert remove_orphans(tmp_path) == [orphan]
    assert not orphan.exists() and fresh.exists() and mine.exists()
    assert old_form.exists() and other.exists()
    # scratch_folder clears them on its way.
    os.utime(fresh, (hour_ago, hour_ago))
    os.utime(fresh / "nbv-exr-inner", (hour_ago, hour_ago))
    os.utime(fresh / "nbv-exr-inner" / "depth.exr", (hour_ago, hour_ago))
    scratch_folder(tmp_path, 1, ram=tmp_path)
    assert not fresh.exists() and mine.exists()


_EXR_CHECK = """
import json, sys
import numpy as np
import OpenEXR
sys.path.insert(0, sys.argv[1])
import render_depth
folder = sys.argv[2]
rng = np.random.default_rng(0)
rgba = rng.normal(size=(5, 7, 4)).astype(np.float32)
found = {}
for name, compression, dtype in [("plain", OpenEXR.NO_COMPRESSION, np.float32),
                                 ("zip", OpenEXR.ZIP_COMPRESSION, np.float32),
                                 ("half", OpenEXR.NO_COMPRESSION, np.float16)]:
    path = f"{folder}/{name}.exr"
    header = {"compression": compression, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGBA": rgba.astype(dtype)}) as exr:
        exr.write(path)
    try:
        red, alpha = render_depth.exr_channels(open(path, "rb").read(), 7, 5, path)
        same = np.array_equal(red, rgba[..., 0]) and np.array_equal(alpha, rgba[..., 3])
        found[name] = bool(same)
    except RuntimeError as err:
        found[name] = str(err)
print(json.dumps(found))
"""


@pytest.mark.blender
def test_exr_reader_agrees_with_openexr(tmp_path):
    """The Blender script's own EXR reader gives the R and A planes OpenEXR's binding wrote, bit
    for bit, and refuses a compressed or half-float file by name."""
    run = subprocess.run(
        [sys.executable, "-c", _EXR_CHECK, str(BLENDER_SCRIPT.parent), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    found = json.loads(run.stdout.splitlines()[-1])
    assert found["plain"] is True
    assert "zip.exr" in found["zip"] and "compressed" in found["zip"]
    assert "half.exr" in found["half"] and "type 1" in found["half"]


def _counted_boxes(count: int, taken: list[str]) -> Iterator[RenderJob]:
    """``count`` one-view box jobs, each key appended to ``taken`` as the job is read."""
    box = _box_at_x()
    for i in range(count):
        taken.append(f"m{i}")
        yield RenderJob(f"m{i}", box.vertices, box.faces, POSES[:1])


@pytest.mark.blender
@pytest.mark.slow
def test_blender_reads_the_jobs_as_it_renders(tmp_path):
    """A process is handed its next mesh as it finishes one: when the first depth arrives, only
    that mesh and the one held ready have been read from the jobs."""
    taken: list[str] = []
    read_at_result = []
    for key, depth in render(_counted_boxes(4, taken), CAMERA, workdir=tmp_path, threads=1):
        read_at_result.append(len(taken))
        assert depth.shape == (1, CAMERA.height, CAMERA.width), key
    assert read_at_result[0] == 2 and read_at_result[-1] == 4
    assert not any(tmp_path.iterdir())


@pytest.mark.blender
@pytest.mark.slow
def test_blender_processes_wait_for_a_slow_consumer(tmp_path):
    """Two processes whose consumer lags stop asking for meshes: at most 2 queued results a
    process, and each holds one rendered and one waiting mesh, so 9 of 20 are read at most."""
    taken: list[str] = []
    results = render(_counted_boxes(20, taken), CAMERA, workdir=tmp_path, threads=1, processes=2)
    next(results)
    time.sleep(3)  # unbounded, two processes render the 19 others of 1 view each meanwhile
    assert len(taken) <= 9, taken
    assert len(list(results)) == 19 and len(taken) == 20


def _script_job(tmp_path: Path, entries: list[dict]) -> Path:
    job = {"width": 32, "height": 24, "fx": 30.0, "fy": 30.0, "cx": 15.5, "cy": 11.5}
    path = tmp_path / "job.json"
    path.write_text(json.dumps(job | {"threads": 1, "device": "CPU", "jobs": entries}))
    return path


@pytest.mark.blender
@pytest.mark.slow
def test_blender_script_protocol(tmp_path):
    """Missing and corrupt mesh files fail alone; a bad job file is fatal."""
    box = _box_at_x()
    np.savez(tmp_path / "box.npz", vertices=box.vertices, faces=box.faces)
    (tmp_path / "corrupt.npz").write_bytes(b"not a zip file")
    np.save(tmp_path / "poses.npy", opencv_to_blender(POSES[:2]))
    entries = [
        {"key": name, "mesh": str(tmp_path / f"{name}.npz"), "poses": str(tmp_path / "poses.npy"),
         "out": str(tmp_path / f"{name}.npy")}
        for name in ("missing", "corrupt", "box")
    ]  # fmt: skip
    cpu = min(os.sched_getaffinity(0))
    run = subprocess.run(
        [sys.executable, str(BLENDER_SCRIPT), "--job", str(_script_job(tmp_path, entries))],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "NBV_BLENDER_CPUS": str(cpu), "NBV_BLENDER_NICE": "3"},
    )
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert lines[0].startswith("NBV-INFO blender=5.0.1 ") and "binary=bpy-module" in lines[0]
    # Bound to the one CPU it was given, at a priority 3 below this process's.
    assert lines[0].endswith(f" cpus=1 nice={min(19, os.nice(0) + 3)}"), lines[0]
    assert [line.split()[:2] for line in lines[1:]] == [
        ["NBV-FAIL", "missing"],
        ["NBV-FAIL", "corrupt"],
        ["NBV-DONE", "box"],
    ], run.stdout
    depth = np.load(tmp_path / "box.npy")
    assert depth.shape == (2, 24, 32) and depth.dtype == np.float32
    assert not (tmp_path / "missing.npy").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith("nbv-exr-")] == []

    bad = _script_job(tmp_path, entries)
    bad.write_text(bad.read_text().replace('"device": "CPU"', '"device": "TPU"'))
    run = subprocess.run(
        [sys.executable, str(BLENDER_SCRIPT), "--job", str(bad)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 2
    info, fatal = run.stdout.splitlines()
    assert info.startswith("NBV-INFO ") and fatal.startswith("NBV-FATAL ") and "TPU" in fatal
    # Not bound: every CPU, this process's priority.
    assert info.endswith(f" cpus={len(os.sched_getaffinity(0))} nice={os.nice(0)}")


@pytest.mark.blender
def test_blender_crash_restarts_for_the_rest(tmp_path):
    """Killing the Blender process fails the mesh it was on; a new process renders the rest."""
    box, parts = _box_at_x(), _two_parts()
    jobs = [
        RenderJob("first", box.vertices, box.faces, POSES),
        RenderJob("second", parts.vertices, parts.faces, POSES[:2]),
        RenderJob("third", box.vertices, box.faces, POSES[:2]),
    ]
    killed: list[int] = []
    # Children this process already has (multiprocessing's resource tracker, once an earlier
    # test used a process pool) are not the renderer's: only a new child is killed.
    others = set(_children())

    def kill_first_child() -> None:
        # Blender needs about a second to start, so the first mesh cannot be done yet.
        deadline = time.monotonic() + 60
        while not killed and time.monotonic() < deadline:
            for pid in set(_children()) - others:
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
            time.sleep(0.005)

    killer = threading.Thread(target=kill_first_child)
    killer.start()
    try:
        results = dict(render(jobs, CAMERA, workdir=tmp_path))
    finally:
        killed.append(-1)
        killer.join()
    assert list(results) == ["first", "second", "third"]
    assert isinstance(results["first"], RenderError)
    assert "SIGKILL" in str(results["first"]) and "blender.log" in str(results["first"])
    expected = render_raycast(box.vertices, box.faces, POSES[:2], CAMERA)
    assert _agreement(results["third"][0], expected[0])[0] >= 0.99
    assert results["second"].shape == (2, CAMERA.height, CAMERA.width)


# ---------------------------------------------------------------------------------------------
# Benchmark helpers


def test_bench_mesh_is_a_closed_50k_triangle_surface():
    from nbv.bench.render import bumpy_torus

    vertices, faces = bumpy_torus()
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert len(faces) == 50_000 and mesh.is_watertight
    assert np.linalg.norm(vertices, axis=1).max() < 0.5
    assert mesh.euler_number == 0  # a torus


def test_agreement_statistics():
    from nbv.bench.render import agreement

    first = np.array([[1.0, 2.0, np.inf, 4.0], [np.inf, 1.0, 1.0, 1.0]], dtype=np.float32)
    second = np.array([[1.0, 2.00005, 3.0, np.inf], [np.inf, 1.0, 1.001, 1.0]])
    stats = agreement(first, second)
    assert stats["common"] == 5 and stats["mask_mismatch"] == 2
    assert stats["within"] == pytest.approx(4 / 5)
    assert stats["max"] == pytest.approx(0.001, rel=1e-4)


def test_ray_culling_changes_nothing():
    """Casting only the reachable pixels gives exactly the image of casting every pixel."""
    from nbv.render.raycast import reachable_pixels

    intrinsics = Intrinsics.centred(96, 72, 70.0)
    parts = [trimesh.creation.box((0.1, 0.6, 0.1)), trimesh.creation.icosphere(2, 0.15)]
    parts[1].apply_translation([0.25, 0.2, -0.1])
    mesh = trimesh.util.concatenate(parts)
    poses = viewspace_poses(original_viewspace())
    culled = render_raycast(mesh.vertices, mesh.faces, poses, intrinsics)
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(mesh.vertices.astype(np.float32)),
        o3d.core.Tensor(mesh.faces.astype(np.uint32)),
    )
    for pose, image in zip(poses, culled, strict=True):
        mask = reachable_pixels(mesh.vertices, mesh.faces, pose, intrinsics)
        assert 0.0 < mask.mean() < 0.6  # the culling does cull
        assert mask[np.isfinite(image)].all()
        d = pixel_rays(intrinsics).reshape(-1, 3) @ pose[:3, :3].T
        rays = np.concatenate([np.broadcast_to(pose[:3, 3], d.shape), d], axis=1)
        every = scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))["t_hit"].numpy()
        every = every.reshape(image.shape)
        assert np.array_equal(np.isfinite(every), np.isfinite(image))
        # Rays built in float32 here and in float64 there: depth agrees to float32 rounding.
        np.testing.assert_allclose(image[np.isfinite(image)], every[np.isfinite(every)], atol=1e-5)


# -- the depth-sensor noise model ---------------------------------------------------------------


def _plane_depth(tilt_deg: float, intrinsics: Intrinsics) -> np.ndarray:
    """Ray-cast depth of a large square through the origin, seen from (0, 0, -1) looking at the
    origin, its normal tilted ``tilt_deg`` from the camera's axis: (1, H, W)."""
    t = np.radians(tilt_deg)
    quad = np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], dtype=float)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    pose = np.eye(4)
    pose[:3, 3] = [0, 0, -1]  # OpenCV camera axes: it looks along +z, at the origin
    return render_raycast(quad @ rot.T, np.array([[0, 1, 2], [0, 2, 3]]), pose[None], intrinsics)


def test_depth_noise_has_the_axial_sigma_and_grazing_dropout():
    cam = Intrinsics.centred(160, 120, 119.0)
    rng = np.random.default_rng
    noise = DepthNoise()
    # Facing the camera at depth 1: incidence near 0 in the centre, sigma = a + b (1 - z0)^2.
    flat = _plane_depth(0.0, cam)
    angle = incidence_angles(flat[0], cam)
    assert np.degrees(angle[60, 80]) < 1.0 and angle[0, 0] == pytest.approx(np.pi / 2)
    noisy = noisy_depth(flat, cam, noise, rng(0))
    centre = (slice(50, 70), slice(70, 90))
    sigma = noise.a + noise.b * (1.0 - noise.z0) ** 2
    assert np.std(noisy[0][centre] - flat[0][centre]) == pytest.approx(sigma, rel=0.1)
    assert np.isfinite(noisy[0][centre]).all()  # no dropout far from grazing
    # Tilted 80 degrees: dropout probability (80 - 70) / (90 - 70) = 0.5 near the centre.
    steep = _plane_depth(80.0, cam)
    assert np.degrees(incidence_angles(steep[0], cam)[60, 80]) == pytest.approx(80.0, abs=1.0)
    window = (slice(55, 65), slice(75, 85))
    kept = np.isfinite(noisy_depth(steep, cam, noise, rng(0))[0][window]).mean()
    assert kept == pytest.approx(0.5, abs=0.1)
    # Seeded; the input stays untouched; background stays background.
    again = noisy_depth(flat, cam, noise, rng(0))
    np.testing.assert_array_equal(noisy, again)
    assert not np.array_equal(noisy, noisy_depth(flat, cam, noise, rng(1)))
    assert np.isinf(noisy_depth(np.full((1, 120, 160), np.inf), cam, noise, rng(0))).all()
    with pytest.raises(ValueError, match="dropout_start"):
        DepthNoise(dropout_start=95.0)
