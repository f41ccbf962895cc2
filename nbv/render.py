"""Depth rendering of meshes: Blender Cycles (the default) or Open3D ray casting.

Both backends share the camera model of :mod:`nbv.camera` and return planar depth, ``inf`` for
background, as (V, H, W) float32 arrays, one per mesh:

* ``"blender"`` runs ``blender_scripts/render_depth.py`` in ONE subprocess (the bpy wheel, or a
  Blender binary given by path) for a whole stream of meshes and yields each mesh's depth as soon
  as it is done, so the caller overlaps its own work with rendering.
* ``"raycast"`` casts one ray per pixel centre with Open3D's Embree scene, in this process.

Per-mesh failures come back as :class:`RenderError` values in the stream instead of exceptions,
so one bad mesh never costs the rest of a shard.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nbv.camera import Intrinsics, opencv_to_blender, pixel_rays

#: The Blender script, run as a subprocess (it imports bpy, never nbv).
BLENDER_SCRIPT = Path(__file__).resolve().parent.parent / "blender_scripts" / "render_depth.py"
BACKENDS = ("blender", "raycast")
DEVICES = ("CPU", "GPU", "AUTO")
_STDERR_TAIL_LINES = 20


class RenderError(RuntimeError):
    """Rendering one mesh failed; the message names its key and the reason."""


@dataclass(frozen=True)
class RenderJob:
    """One mesh to render from several cameras.

    Attributes:
        key: unique name of the mesh in the stream (echoed back with its depth).
        vertices: (N, 3) float vertex positions, world units.
        faces: (F, 3) integer vertex indices of triangles.
        poses: (V, 4, 4) camera-to-world matrices in the OpenCV convention of :mod:`nbv.camera`.
    """

    key: str
    vertices: np.ndarray
    faces: np.ndarray
    poses: np.ndarray


def _check_mesh(vertices: np.ndarray, faces: np.ndarray, poses: np.ndarray) -> None:
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"vertices must be (N, 3), got shape {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise ValueError(f"faces must be integer (F, 3), got {faces.dtype} {faces.shape}")
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise ValueError(
            f"face indices must lie in [0, {len(vertices)}), got [{faces.min()}, {faces.max()}]"
        )
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise ValueError(f"poses must be (V, 4, 4), got shape {poses.shape}")


def render_raycast(
    vertices: np.ndarray,
    faces: np.ndarray,
    poses: np.ndarray,
    intrinsics: Intrinsics,
    *,
    threads: int = 0,
) -> np.ndarray:
    """Planar depth images of a triangle mesh by ray casting (Open3D / Embree).

    Rays go through the pixel centres of :func:`nbv.camera.pixel_rays` with unit camera-z, so the
    hit distance along the unnormalised ray is the planar depth.

    Args:
        vertices: (N, 3) vertex positions, world units.
        faces: (F, 3) integer triangle indices.
        poses: (V, 4, 4) camera-to-world, OpenCV convention.
        intrinsics: the camera.
        threads: threads for Embree; 0 = all cores.

    Returns:
        (V, H, W) float32 planar depth, world units; ``inf`` where no triangle is hit.
    """
    import open3d as o3d  # imported here: heavy, and only this backend needs it

    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    poses = np.asarray(poses, dtype=np.float64)
    _check_mesh(vertices, faces, poses)
    depth = np.full((len(poses), intrinsics.height, intrinsics.width), np.inf, dtype=np.float32)
    if faces.size == 0:
        return depth
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.ascontiguousarray(vertices, dtype=np.float32)),
        o3d.core.Tensor(np.ascontiguousarray(faces, dtype=np.uint32)),
    )
    # One float32 product per view gives every ray: [x, y, 1, 1] @ [[0, R^T], [c, 0]] puts the
    # camera centre c in the first three columns and R @ [x, y, 1] in the last three.
    pixels = np.ones((intrinsics.height * intrinsics.width, 4), dtype=np.float32)
    pixels[:, :2] = pixel_rays(intrinsics).reshape(-1, 3)[:, :2]
    transform = np.zeros((4, 6), dtype=np.float32)
    for i, pose in enumerate(poses):
        transform[:3, 3:] = pose[:3, :3].T
        transform[3, :3] = pose[:3, 3]
        reach = np.flatnonzero(reachable_pixels(vertices, faces, pose, intrinsics).ravel())
        rays = o3d.core.Tensor.from_numpy(pixels[reach] @ transform)
        depth[i].ravel()[reach] = scene.cast_rays(rays, nthreads=threads)["t_hit"].numpy()
    return depth


def reachable_pixels(
    vertices: np.ndarray, faces: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, tile: int = 8
) -> np.ndarray:
    """A conservative mask of the pixels whose rays can hit the mesh: (H, W) bool.

    A triangle in front of the camera projects inside the pixel bounding box of its projected
    corners, so the union of those boxes (rounded out to ``tile`` x ``tile`` blocks, which keeps
    the count cheap) holds every pixel that can see it. Ray casting only those pixels gives the
    same depth image for a fraction of the rays. A mesh reaching behind the camera plane, or one
    with more than a triangle per 16 pixels, gets every pixel.
    """
    rotation, centre = pose[:3, :3], pose[:3, 3]
    cam = (np.asarray(vertices, dtype=np.float64) - centre) @ rotation
    full = np.ones((intrinsics.height, intrinsics.width), dtype=bool)
    # The mask costs O(F): past about one triangle per 16 pixels it costs more than it saves.
    if not np.all(cam[:, 2] > 1e-9) or 16 * len(faces) > full.size:
        return full
    u = intrinsics.fx * cam[:, 0] / cam[:, 2] + intrinsics.cx
    v = intrinsics.fy * cam[:, 1] / cam[:, 2] + intrinsics.cy
    tu, tv = -(-intrinsics.width // tile), -(-intrinsics.height // tile)
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    # Pixel centres are integers: a box [lo, hi] holds the pixels ceil(lo)..floor(hi). (Column
    # minima by np.minimum are several times faster than .min(axis=1) on (F, 3) arrays.)
    u0 = np.clip(np.ceil(np.minimum(np.minimum(u[a], u[b]), u[c])) // tile, 0, tu).astype(np.int64)
    u1 = np.clip(np.floor(np.maximum(np.maximum(u[a], u[b]), u[c])) // tile + 1, 0, tu)
    v0 = np.clip(np.ceil(np.minimum(np.minimum(v[a], v[b]), v[c])) // tile, 0, tv).astype(np.int64)
    v1 = np.clip(np.floor(np.maximum(np.maximum(v[a], v[b]), v[c])) // tile + 1, 0, tv)
    u1, v1 = u1.astype(np.int64), v1.astype(np.int64)
    keep = (u1 > u0) & (v1 > v0)
    u0, u1, v0, v1 = u0[keep], u1[keep], v0[keep], v1[keep]
    # Two-dimensional difference array of the boxes, summed up: tiles covered by some box.
    stride = tu + 1
    corners = np.concatenate(
        [v0 * stride + u0, v0 * stride + u1, v1 * stride + u0, v1 * stride + u1]
    )
    weights = np.concatenate(
        [np.ones_like(u0), -np.ones_like(u0), -np.ones_like(u0), np.ones_like(u0)]
    )
    counts = np.bincount(corners, weights, minlength=(tv + 1) * stride).reshape(tv + 1, stride)
    tiles = counts.cumsum(axis=0).cumsum(axis=1)[:tv, :tu] > 0.5
    mask = np.repeat(np.repeat(tiles, tile, axis=0), tile, axis=1)
    return mask[: intrinsics.height, : intrinsics.width]


def _intrinsics_spec(intrinsics: Intrinsics) -> dict:
    return {
        "width": intrinsics.width,
        "height": intrinsics.height,
        "fx": float(intrinsics.fx),
        "fy": float(intrinsics.fy),
        "cx": float(intrinsics.cx),
        "cy": float(intrinsics.cy),
    }


def _check_options(threads: int, device: str = "CPU", blender: str | None = None) -> None:
    if not isinstance(threads, int | np.integer) or threads < 0:
        raise ValueError(f"threads must be an integer >= 0 (0 = all cores), got {threads!r}")
    if device not in DEVICES:
        raise ValueError(f"device must be one of {DEVICES}, got {device!r}")
    if blender is not None and shutil.which(blender) is None:
        raise FileNotFoundError(f"Blender executable {blender!r} not found")


def _blender_command(blender: str | None, job_file: Path) -> list[str]:
    if blender is None:
        return [sys.executable, str(BLENDER_SCRIPT), "--job", str(job_file)]
    # --python-exit-code: a Python error in the script must not end as a clean exit.
    return [blender, "-b", "--factory-startup", "--python-exit-code", "1", "-P",
            str(BLENDER_SCRIPT), "--", "--job", str(job_file)]  # fmt: skip


def _exit_reason(status: int) -> str:
    if status < 0:
        try:
            return f"killed by signal {-status} ({signal.Signals(-status).name})"
        except ValueError:
            return f"killed by signal {-status}"
    return f"exit status {status}"


def _log_tail(log: Path, offset: int, lines: int = _STDERR_TAIL_LINES) -> str:
    with open(log, "rb") as f:
        f.seek(offset)
        text = f.read().decode("utf-8", errors="replace")
    return "\n".join(text.splitlines()[-lines:])


@dataclass(frozen=True)
class _Pending:
    key: str
    mesh: Path
    poses: Path
    out: Path

    def entry(self) -> dict:
        return {"key": self.key, "mesh": str(self.mesh), "poses": str(self.poses),
                "out": str(self.out)}  # fmt: skip

    def remove(self) -> None:
        for path in (self.mesh, self.poses, self.out):
            path.unlink(missing_ok=True)


def _stage(job: RenderJob, index: int, run_dir: Path) -> _Pending:
    """Check a job and write its mesh and Blender-convention poses into run_dir."""
    if not isinstance(job.key, str) or not job.key.strip() or len(job.key.splitlines()) != 1:
        raise ValueError(f"key must be a non-empty one-line string, got {job.key!r}")
    vertices, faces, poses = (np.asarray(a) for a in (job.vertices, job.faces, job.poses))
    _check_mesh(vertices, faces, poses)
    if not (np.all(np.isfinite(vertices)) and np.all(np.isfinite(poses))):
        raise ValueError("vertices and poses must be finite")
    pending = _Pending(
        job.key, run_dir / f"{index:06d}_mesh.npz", run_dir / f"{index:06d}_poses.npy",
        run_dir / f"{index:06d}_depth.npy",
    )  # fmt: skip
    np.savez(pending.mesh, vertices=vertices.astype(np.float64), faces=faces.astype(np.int64))
    np.save(pending.poses, opencv_to_blender(poses))
    return pending


def render_blender(
    jobs: Iterable[RenderJob],
    intrinsics: Intrinsics,
    workdir: Path,
    blender: str | None = None,
    threads: int = 0,
    device: str = "CPU",
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    """Render meshes with Blender Cycles in one subprocess, yielding each as soon as it is done.

    All jobs are staged into a fresh folder under ``workdir`` first (meshes as .npz, poses
    converted to Blender's camera convention), then ``blender_scripts/render_depth.py`` renders
    them in order in one process. If that process dies before finishing, the mesh it was
    rendering gets a :class:`RenderError` (exit status and the tail of Blender's output) and a new
    process renders the rest. Blender's output goes to ``blender.log`` in that folder; the folder
    is removed at the end unless something failed, when the log is kept and named in the errors.

    Args:
        jobs: meshes with keys and OpenCV camera-to-world poses; keys must be unique.
        intrinsics: the camera, shared by every view.
        workdir: folder for temporary files (created if missing).
        blender: path of a Blender 4.x/5.x executable; None runs the script with this Python's
            ``bpy`` module.
        threads: CPU threads for Cycles; 0 = all cores.
        device: "CPU", "GPU" (fail without one) or "AUTO" (GPU when present).

    Yields:
        ``(key, depth)`` with (V, H, W) float32 planar depth, ``inf`` for background, or
        ``(key, RenderError)``, in job order (invalid jobs are reported first).

    Raises:
        ValueError: bad ``threads``/``device``; FileNotFoundError: ``blender`` not found.
    """
    _check_options(threads, device, blender)
    if not BLENDER_SCRIPT.is_file():
        raise FileNotFoundError(f"{BLENDER_SCRIPT} is missing: nbv must run from a checkout")
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    return _render_blender(jobs, intrinsics, workdir, blender, threads, device)


def _render_blender(
    jobs: Iterable[RenderJob],
    intrinsics: Intrinsics,
    workdir: Path,
    blender: str | None,
    threads: int,
    device: str,
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    run_dir = Path(tempfile.mkdtemp(prefix="blender-", dir=workdir))
    log = run_dir / "blender.log"
    failed = False
    process: subprocess.Popen | None = None
    pending: list[_Pending] = []
    try:
        seen: set[str] = set()
        for index, job in enumerate(jobs):
            try:
                if job.key in seen:
                    raise ValueError("duplicate key")
                pending.append(_stage(job, index, run_dir))
                seen.add(job.key)
            except (ValueError, TypeError, AttributeError) as exc:
                key = getattr(job, "key", f"#{index}")
                yield key, RenderError(f"{key!r}: {exc}")
        spec = _intrinsics_spec(intrinsics) | {"threads": int(threads), "device": device}
        run = 0
        while pending:
            job_file = run_dir / f"job_{run:03d}.json"
            job_file.write_text(json.dumps(spec | {"jobs": [p.entry() for p in pending]}))
            with open(log, "ab") as log_file:
                log_file.write(f"=== run {run}: {len(pending)} meshes ===\n".encode())
                offset = log_file.tell()
                process = subprocess.Popen(
                    _blender_command(blender, job_file),
                    stdout=subprocess.PIPE,
                    stderr=log_file,
                    stdin=subprocess.DEVNULL,
                    text=True,
                    errors="replace",
                )
            fatal = None
            assert process.stdout is not None
            for line in process.stdout:
                if line.startswith("NBV-FATAL "):
                    fatal = line[len("NBV-FATAL ") :].strip()
                    continue
                if not line.startswith(("NBV-DONE ", "NBV-FAIL ")) or not pending:
                    with open(log, "a") as log_file:
                        log_file.write(line)
                    continue
                job = pending[0]
                tag, rest = line.rstrip("\n").split(" ", 1)
                if rest != job.key and not rest.startswith(job.key + " "):
                    raise RenderError(f"Blender reported {rest!r} while {job.key!r} was expected")
                if tag == "NBV-DONE":
                    result: np.ndarray | RenderError = np.load(job.out)
                else:
                    failed = True
                    result = RenderError(f"{job.key!r}: {rest[len(job.key) :].strip()}")
                job.remove()
                pending.pop(0)
                yield job.key, result
            status = process.wait()
            process = None
            if not pending:
                break
            failed = True
            if fatal is not None:
                for job in pending:
                    job.remove()
                    yield job.key, RenderError(f"{job.key!r}: Blender could not start: {fatal}")
                pending.clear()
                break
            job = pending.pop(0)
            job.remove()
            yield (
                job.key,
                RenderError(
                    f"{job.key!r}: Blender died ({_exit_reason(status)}) while rendering it; "
                    f"log {log}, last lines:\n{_log_tail(log, offset)}"
                ),
            )
            run += 1
    finally:
        if process is not None and process.poll() is None:
            process.kill()
            process.wait()
        if failed:  # keep only the log
            for path in run_dir.iterdir():
                if path.is_dir():
                    shutil.rmtree(path, ignore_errors=True)
                elif path != log:
                    path.unlink()
        else:
            shutil.rmtree(run_dir, ignore_errors=True)


def render(
    jobs: Iterable[RenderJob],
    intrinsics: Intrinsics,
    backend: str = "blender",
    workdir: Path | None = None,
    **kw,
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    """Render a stream of meshes with either backend; failures come back as RenderError values.

    Args:
        jobs: meshes with unique keys and OpenCV camera-to-world poses.
        intrinsics: the camera.
        backend: "blender" (default, :func:`render_blender`) or "raycast" (:func:`render_raycast`).
        workdir: temporary folder for the Blender backend; None makes one under the system's
            temporary folder (removed afterwards unless a log had to be kept).
        **kw: backend options: ``blender``, ``threads``, ``device`` for "blender"; ``threads``
            for "raycast".

    Yields:
        ``(key, depth or RenderError)``; depth is (V, H, W) float32 planar depth, inf background.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    allowed = {"blender": {"blender", "threads", "device"}, "raycast": {"threads"}}[backend]
    if set(kw) - allowed:
        raise ValueError(
            f"backend {backend!r} takes options {sorted(allowed)}, got {sorted(set(kw) - allowed)}"
        )
    if backend == "raycast":
        _check_options(kw.get("threads", 0))
        return _render_raycast_stream(jobs, intrinsics, kw.get("threads", 0))
    if workdir is not None:
        return render_blender(jobs, intrinsics, Path(workdir), **kw)
    _check_options(kw.get("threads", 0), kw.get("device", "CPU"), kw.get("blender"))
    return _in_temporary_dir(jobs, intrinsics, kw)


def _in_temporary_dir(
    jobs: Iterable[RenderJob], intrinsics: Intrinsics, kw: dict
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    workdir = Path(tempfile.mkdtemp(prefix="nbv-blender-"))
    try:
        yield from render_blender(jobs, intrinsics, workdir, **kw)
    finally:
        # Left in place when it still holds a log kept for a failure.
        if not any(workdir.iterdir()):
            workdir.rmdir()


def _render_raycast_stream(
    jobs: Iterable[RenderJob], intrinsics: Intrinsics, threads: int
) -> Iterator[tuple[str, np.ndarray | RenderError]]:
    for job in jobs:
        try:
            depth = render_raycast(job.vertices, job.faces, job.poses, intrinsics, threads=threads)
        except Exception as exc:  # one bad mesh must not stop the stream
            yield job.key, RenderError(f"{job.key!r}: {type(exc).__name__}: {exc}")
        else:
            yield job.key, depth
