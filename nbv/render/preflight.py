"""Check a Blender once before a batch: it starts, is a supported version, imports numpy and
renders correct depth.

A cluster's Blender is whatever its module system or its operating system offers, so a batch
first renders one tiny scene with it, through ``blender_scripts/render_depth.py`` exactly as the
batch will: a cube of half-size 0.25 at the origin seen face-on from distance 1, 32 x 24 pixels,
focal length 30 px. Its depth is known exactly: 0.75 on a 20 x 20 block of pixels in the middle
(their centres lie at least half a pixel inside the face's edges), background elsewhere. When the
Blender cannot do that, :func:`check_blender` raises one :class:`PreflightError` that says what to
install or which versions are supported, and no model is tried.
"""

from __future__ import annotations

import json
import logging
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nbv.geometry.camera import Intrinsics, look_at
from nbv.render.blender import (
    SUPPORTED_TEXT,
    blender_command,
    check_options,
    exit_reason,
    job_spec,
    stage_job,
)
from nbv.render.job import RenderJob

log = logging.getLogger(__name__)

#: The test scene's camera: 32 x 24 pixels, focal length 30 px, principal point at the centre.
PREFLIGHT_CAMERA = Intrinsics.centred(32, 24, 30.0)
#: Half the cube's edge, world units; the camera sits at distance 1 on +z, so the face is at 0.75.
_HALF = 0.25
#: Depth tolerance on the face, world units (the depth is float32 radiance, exact to ~1e-7).
_TOL = 1e-4
#: Lines of Blender's output quoted when it failed for a reason the script could not report.
_TAIL_LINES = 15


class PreflightError(ValueError):
    """The configured Blender cannot render; the message names it and says what to do."""


@dataclass(frozen=True)
class BlenderInfo:
    """What rendered the test scene.

    Attributes:
        blender: the executable, or None for this Python's ``bpy`` module.
        version: Blender's version, e.g. (3, 4, 1).
        python: the version of Blender's Python, e.g. "3.11.2".
        numpy: the version of numpy in that Python.
        seconds: wall-clock seconds of the test run (start-up included).
    """

    blender: str | None
    version: tuple[int, ...]
    python: str
    numpy: str
    seconds: float


def preflight_scene() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The test scene and its exact depth.

    Returns:
        (8, 3) float64 cube vertices, (12, 3) int64 outward triangles, (1, 4, 4) OpenCV
        camera-to-world pose (distance 1 on +z, looking at the origin) and the expected
        (H, W) float32 depth of :data:`PREFLIGHT_CAMERA`, ``inf`` for background.
    """
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
        dtype=np.int64,
    )  # fmt: skip
    pose = look_at(np.array([0.0, 0.0, 1.0]))[None]
    k = PREFLIGHT_CAMERA
    u = np.abs(np.arange(k.width) - k.cx) / k.fx * (1.0 - _HALF)
    v = np.abs(np.arange(k.height) - k.cy) / k.fy * (1.0 - _HALF)
    inside = (v[:, None] < _HALF) & (u[None, :] < _HALF)
    depth = np.where(inside, np.float32(1.0 - _HALF), np.float32(np.inf)).astype(np.float32)
    return corners * _HALF, faces, pose, depth


def _who(blender: str | None) -> str:
    return f"Blender {blender!r}" if blender is not None else f"the bpy module of {sys.executable}"


def _parse_info(line: str) -> dict[str, str]:
    """``NBV-INFO blender=3.4.1 python=3.11.2 ...`` as a dict (the script's first line)."""
    return dict(re.findall(r"(\w+)=(\S+)", line))


def _version_of(blender: str) -> str | None:
    """The first line of ``blender --version`` (e.g. "Blender 2.79 (sub 7)"), or None."""
    try:
        run = subprocess.run(
            [blender, "--version"], capture_output=True, text=True, timeout=120, check=False
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    lines = [line for line in run.stdout.splitlines() if line.startswith("Blender ")]
    return lines[0].strip() if lines else None


def _no_script_message(who: str, blender: str | None, status: int, tail: str) -> str:
    """The script never started: too old a Blender for its Python syntax, or a broken one."""
    version = _version_of(blender) if blender is not None else None
    said = f" (`--version`: {version})" if version else ""
    return (
        f"{who}{said} could not run blender_scripts/render_depth.py ({exit_reason(status)}); "
        f"supported are Blender {SUPPORTED_TEXT}. Last lines of its output: {tail}"
    )


def _check_depth(who: str, depth: np.ndarray, expected: np.ndarray) -> None:
    hit, want = np.isfinite(depth), np.isfinite(expected)
    if not hit.any():
        raise PreflightError(
            f"{who} renders nothing: a cube in front of the camera came out as empty background "
            f"(blender_scripts/render_depth.py does not handle this Blender; supported are "
            f"{SUPPORTED_TEXT})"
        )
    with np.errstate(invalid="ignore"):  # inf - inf where both are background
        wrong = (hit != want) | (hit & (np.abs(depth - expected) > _TOL))
    if wrong.any():
        seen = np.median(depth[hit])
        raise PreflightError(
            f"{who} renders wrong depth: {int(wrong.sum())} of {depth.size} pixels of the test "
            f"cube differ (face depth {seen:.6f}, expected {1.0 - _HALF}, {int(hit.sum())} "
            f"pixels hit, expected {int(want.sum())}); supported are {SUPPORTED_TEXT}"
        )


def _reported_info(who: str, blender: str | None, run: subprocess.CompletedProcess) -> dict:
    """The ``NBV-INFO`` line of a preflight run that rendered the test cube.

    Raises:
        PreflightError: the script reported a failure, never ran, or died before it was done.
    """
    lines = run.stdout.splitlines()
    info = next((_parse_info(x) for x in lines if x.startswith("NBV-INFO ")), None)
    tail = " | ".join(run.stderr.strip().splitlines()[-_TAIL_LINES:])
    for line in lines:
        tag, _, rest = line.partition(" ")
        if tag == "NBV-FATAL":
            raise PreflightError(f"{who}: {rest}")
        if tag == "NBV-FAIL":
            raise PreflightError(f"{who} failed on the test cube: {rest}")
    if info is None:
        raise PreflightError(_no_script_message(who, blender, run.returncode, tail))
    if "NBV-DONE preflight" not in lines:
        raise PreflightError(
            f"{who} (Blender {info.get('blender')}) died on the test cube "
            f"({exit_reason(run.returncode)}); last lines of its output: {tail}"
        )
    return info


def check_blender(
    blender: str | None,
    threads: int = 0,
    device: str = "CPU",
    workdir: Path | None = None,
    timeout: float = 600.0,
) -> BlenderInfo:
    """Render the test scene once with ``blender`` and check its depth.

    Args:
        blender: a Blender executable (path or name on PATH); None = this Python's bpy module.
        threads, device: as for :func:`nbv.render.blender.render_blender` (a GPU that is not
            there fails here too).
        workdir: folder for the temporary files; None = the system's temporary folder.
        timeout: seconds before a Blender that hangs is killed and reported.

    Returns:
        The :class:`BlenderInfo` of the run (also logged).

    Raises:
        PreflightError: not found, not runnable, an unsupported version, no numpy in its Python,
            no or wrong depth; the message names the executable and says what to do.
    """
    who = _who(blender)
    try:
        check_options(threads, device, blender)
    except FileNotFoundError:
        raise PreflightError(
            f"{who}: no such executable (give a path, or a name on PATH)"
        ) from None
    vertices, faces, pose, expected = preflight_scene()
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="nbv-preflight-", dir=workdir) as folder:
        run_dir = Path(folder)
        staged = stage_job(RenderJob("preflight", vertices, faces, pose), 0, run_dir)
        job_file = run_dir / "job.json"
        spec = job_spec(PREFLIGHT_CAMERA, threads, device) | {"jobs": [staged.entry()]}
        job_file.write_text(json.dumps(spec))
        try:
            run = subprocess.run(
                blender_command(blender, job_file),
                capture_output=True,
                stdin=subprocess.DEVNULL,
                text=True,
                errors="replace",
                timeout=timeout,
                check=False,
            )
        except subprocess.TimeoutExpired:
            raise PreflightError(
                f"{who} did not render a 32 x 24 test view in {timeout:.0f} s"
            ) from None
        except OSError as err:
            raise PreflightError(f"{who} cannot be started: {err}") from None
        info = _reported_info(who, blender, run)
        depth = np.load(staged.out)
    _check_depth(who, depth[0], expected)
    result = BlenderInfo(
        blender=blender,
        version=tuple(int(n) for n in info["blender"].split(".")),
        python=info["python"],
        numpy=info["numpy"],
        seconds=time.perf_counter() - start,
    )
    log.info(
        "preflight: %s is Blender %s (Python %s, numpy %s; supported %s) and renders correct "
        "depth (%.1f s)",
        who, info["blender"], result.python, result.numpy, SUPPORTED_TEXT, result.seconds,
    )  # fmt: skip
    return result
