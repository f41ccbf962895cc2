"""A cluster's Blender binary against the bpy wheel, and the preflight check before a batch.

The binary is Debian 12's ``blender`` package (3.4.1, the oldest supported version), installed
with its ``python3-numpy`` by ``scripts/ensure_blender.sh`` (``.ci/run`` does). In CI a missing
binary fails these tests; elsewhere they skip. ``NBV_TEST_BLENDER`` names another binary.
The sbatch script with ``BLENDER=`` is tested in ``tests/test_dataset_slurm.py``.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from needs import require_binary
from scipy.spatial import cKDTree

from nbv.assets.meshes import Mesh, load_mesh, normalise, sample_surface
from nbv.assets.synthetic import build, catalogue
from nbv.bench.render import agreement
from nbv.geometry.camera import Intrinsics, backproject, opencv_to_blender, viewspace_poses
from nbv.geometry.scores import DEFAULT_EPS, coverage_bits
from nbv.geometry.viewspace import original_viewspace
from nbv.render.backends import render
from nbv.render.blender import BLENDER_SCRIPT, SUPPORTED_TEXT, SUPPORTED_VERSIONS, job_spec
from nbv.render.job import RenderError, RenderJob
from nbv.render.preflight import PREFLIGHT_CAMERA, PreflightError, check_blender, preflight_scene
from nbv.render.raycast import render_raycast

pytestmark = pytest.mark.blender

REPO = Path(__file__).resolve().parents[1]
#: The development meshes beside the checkout (CI has a copy of shared/ beside its clone).
SHARED_MESHES = REPO.parent / "shared" / "meshes"
#: The dataset's camera, and four views of the original viewspace: the pole, 30 degrees up, the
#: equator, 30 degrees down.
CAMERA = Intrinsics.centred()
VIEWS = [0, 9, 20, 30]


@pytest.fixture(scope="module")
def binary() -> str:
    return require_binary()


def binary_version(binary: str) -> tuple[int, ...]:
    """The version ``blender --version`` prints, e.g. (3, 4, 1)."""
    out = subprocess.run([binary, "--version"], capture_output=True, text=True, check=True)
    return tuple(
        int(n) for n in re.search(r"^Blender (\d+)\.(\d+)\.(\d+)", out.stdout, re.M).groups()
    )


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    path.chmod(0o755)
    return path


def without_numpy(binary: str, folder: Path) -> Path:
    """The real binary, its Python unable to import numpy: ``import numpy`` raises ImportError
    as it does on a Debian system without python3-numpy (a None entry in sys.modules, set by a
    --python-expr that Blender runs before the render script)."""
    hide = "import sys; sys.modules['numpy'] = None"
    return _write(
        folder / "blender-without-numpy", f'#!/bin/sh\nexec {binary} --python-expr "{hide}" "$@"\n'
    )


# ---------------------------------------------------------------------------------------------
# The binary against the wheel


def _shared_meshes() -> dict[str, Mesh]:
    if not SHARED_MESHES.is_dir():
        pytest.skip(f"{SHARED_MESHES} is not there (the development meshes beside the checkout)")
    meshes = {p.stem: normalise(load_mesh(p))[0] for p in sorted(SHARED_MESHES.glob("*.obj"))}
    assert len(meshes) == 6
    return meshes


def _synthetic_models() -> dict[str, Mesh]:
    """The first model of every other category of the default synthetic dataset (seed 0): four
    training and four unseen categories."""
    first = {}
    for entry in catalogue():
        first.setdefault(entry.category, entry)
    chosen = list(first.items())[::2]
    return {f"{c}_{e.index}": Mesh(*build(e, 0), c) for c, e in chosen}


def _clouds(depth: np.ndarray, poses: np.ndarray) -> list[np.ndarray]:
    """One mesh's full-resolution view clouds, world frame."""
    return [backproject(d, CAMERA, pose) for d, pose in zip(depth, poses, strict=True)]


#: How far from eps a ground-truth point's nearest view point may lie for the two renderers to
#: disagree on its coverage bit: the depth tolerance the renderers agree within (1e-4).
NEAR_EPS = 1e-4


def _unexplained_bit_differences(
    clouds: tuple[list[np.ndarray], list[np.ndarray]], gt: np.ndarray
) -> list[tuple[int, int, float]]:
    """(view, gt point, distance) of the coverage bits the two renderings disagree on where the
    point's nearest view point (in either rendering) is not within NEAR_EPS of eps: a point that
    close to the threshold may flip with a depth difference the renderers are allowed."""
    bits = [coverage_bits(c, gt, DEFAULT_EPS) for c in clouds]
    differ = np.unpackbits(bits[0] ^ bits[1], axis=1)[:, : len(gt)]
    out = []
    for view, point in zip(*np.nonzero(differ), strict=True):
        near = [cKDTree(c[view]).query(gt[point])[0] for c in clouds]
        if min(abs(d - DEFAULT_EPS) for d in near) > NEAR_EPS:
            out.append((int(view), int(point), float(min(near))))
    return out


@pytest.mark.parametrize("mesh_set", ["shared", "synthetic"])
@pytest.mark.slow
def test_binary_depth_and_coverage_match_the_wheel(binary, mesh_set):
    """The binary and the bpy wheel on the same meshes, at the dataset's 640 x 480: depth within
    1e-4 on >= 99.9% of the pixels both hit, hit masks differing on <= 0.01% of the pixels, and
    equal coverage bits (16384 ground-truth points, eps sqrt(5e-5)) but where a ground-truth
    point's nearest view point lies within 1e-4 of eps, where that depth difference may flip it
    (5 of 131,072 bits did on one of 22 models in an earlier measurement; with eps sqrt(5e-5),
    1 of the teapot's, 2026-12-03)."""
    meshes = _shared_meshes() if mesh_set == "shared" else _synthetic_models()
    poses = viewspace_poses(original_viewspace()[VIEWS])
    jobs = [RenderJob(key, m.vertices, m.faces, poses) for key, m in meshes.items()]
    wheel = dict(render(jobs, CAMERA, threads=2))
    other = dict(render(jobs, CAMERA, blender=binary, threads=2))
    for key, mesh in meshes.items():
        assert not isinstance(wheel[key], RenderError), wheel[key]
        assert not isinstance(other[key], RenderError), other[key]
        stats = agreement(wheel[key], other[key])
        assert stats["within"] >= 0.999, (key, stats)
        assert stats["mask_mismatch"] <= 1e-4 * wheel[key].size, (key, stats)
        assert stats["common"] >= 0.02 * wheel[key].size, (key, stats)  # the object is seen
        gt = sample_surface(mesh, 16384, np.random.default_rng(0))
        clouds = tuple(_clouds(depth[key], poses) for depth in (wheel, other))
        bits = coverage_bits(clouds[0], gt, DEFAULT_EPS)
        assert bits.shape == (len(VIEWS), 2048) and bits.any()
        unexplained = _unexplained_bit_differences(clouds, gt)
        assert not unexplained, (key, f"coverage bits differ away from eps: {unexplained}")


@pytest.mark.slow
def test_the_script_refuses_a_version_outside_the_range(binary, tmp_path):
    """The script, run by the binary, refuses a Blender outside the job's range, naming both."""
    vertices, faces, pose, _ = preflight_scene()
    np.savez(tmp_path / "cube.npz", vertices=vertices, faces=faces)
    np.save(tmp_path / "poses.npy", opencv_to_blender(pose))
    entry = {"key": "cube", "mesh": str(tmp_path / "cube.npz"),
             "poses": str(tmp_path / "poses.npy"), "out": str(tmp_path / "cube.npy")}  # fmt: skip
    spec = job_spec(PREFLIGHT_CAMERA, 1, "CPU") | {"jobs": [entry]}
    spec["blender_versions"] = [[9, 0, 0], [9, 1, 0]]
    (tmp_path / "job.json").write_text(json.dumps(spec))
    run = subprocess.run(
        [binary, "-b", "--factory-startup", "-P", str(BLENDER_SCRIPT), "--",
         "--job", str(tmp_path / "job.json")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    version = ".".join(map(str, binary_version(binary)))
    protocol = [line for line in run.stdout.splitlines() if line.startswith("NBV-")]
    assert run.returncode == 2
    assert protocol[0].startswith(f"NBV-INFO blender={version} ")
    assert protocol[1:] == [
        f"NBV-FATAL Blender {version} is not supported: supported are 9.0.0 <= version < 9.1.0"
    ]
    assert not (tmp_path / "cube.npy").exists()


# ---------------------------------------------------------------------------------------------
# The preflight check


@pytest.mark.slow
def test_preflight_accepts_the_binary_and_the_wheel(binary):
    info = check_blender(binary, threads=1)
    assert info.version == binary_version(binary)
    assert SUPPORTED_VERSIONS[0] <= info.version < SUPPORTED_VERSIONS[1]
    assert info.blender == binary and info.numpy != "missing"
    wheel = check_blender(None, threads=1)
    assert wheel.version == (5, 0, 1) and wheel.python == ".".join(map(str, sys.version_info[:3]))


@pytest.mark.slow
def test_preflight_says_what_to_install_when_numpy_is_missing(binary, tmp_path):
    fake = without_numpy(binary, tmp_path)
    version = ".".join(map(str, binary_version(binary)))
    with pytest.raises(PreflightError) as err:
        check_blender(str(fake), threads=1)
    message = str(err.value)
    assert message.startswith(f"Blender '{fake}': Blender {version}'s Python ")
    assert "cannot import numpy" in message and "apt-get install python3-numpy" in message


@pytest.mark.slow
def test_dataset_refuses_to_start_without_numpy_and_writes_nothing(binary, tmp_path):
    """``python -m nbv.dataset renderer.blender=<a binary without numpy>``: one line, status 2,
    no model tried, no output folder."""
    fake = without_numpy(binary, tmp_path)
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, "-m", "nbv.dataset", f"renderer.blender={fake}", f"out_dir={out}",
         "limit=1", "samples.enabled=false", "progress=false",
         f"hydra.run.dir={tmp_path / 'hydra'}"],
        cwd=REPO, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 2, run.stderr
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith(f"nbv.dataset: Blender '{fake}': ") and "python3-numpy" in last
    assert not out.exists() and not (tmp_path / "hydra").exists()


def _fake_blender(folder: Path, depth: float) -> Path:
    """A program with Blender's command line that answers every job with constant depth."""
    return _write(
        folder / "fake-blender",
        f"""#!{sys.executable}
import json, sys
import numpy as np
spec = json.load(open(sys.argv[sys.argv.index("--job") + 1]))
print("NBV-INFO blender=4.2.0 python=3.11.0 numpy=1.26.4 prefix=/fake binary=fake", flush=True)
for job in spec["jobs"]:
    shape = (len(np.load(job["poses"])), spec["height"], spec["width"])
    np.save(job["out"], np.full(shape, float("{depth}"), np.float32))
    print("NBV-DONE", job["key"], flush=True)
""",
    )


@pytest.mark.parametrize(
    ("depth", "says"),
    [
        (float("inf"), "renders nothing: a cube in front of the camera came out as empty"),
        (0.5, "renders wrong depth: 768 of 768 pixels of the test cube differ (face depth"),
    ],
)
def test_preflight_reports_a_blender_that_renders_nothing_or_wrong_depth(tmp_path, depth, says):
    fake = _fake_blender(tmp_path, depth)
    with pytest.raises(PreflightError) as err:
        check_blender(str(fake))
    assert str(err.value).startswith(f"Blender '{fake}' {says}")
    assert SUPPORTED_TEXT in str(err.value)


def test_preflight_names_the_version_of_a_blender_too_old_for_the_script(tmp_path):
    """A Blender whose Python cannot even parse the script (2.7x: Python 3.5) prints no protocol
    line: the check asks it for --version and names the supported range."""
    fake = _write(
        tmp_path / "blender-2.79",
        "#!/bin/sh\n"
        'if [ "$1" = --version ]; then echo "Blender 2.79 (sub 7)"; exit 0; fi\n'
        'echo "SyntaxError: invalid syntax" >&2; exit 1\n',
    )
    with pytest.raises(PreflightError) as err:
        check_blender(str(fake))
    assert str(err.value) == (
        f"Blender '{fake}' (`--version`: Blender 2.79 (sub 7)) could not run "
        f"blender_scripts/render_depth.py (exit status 1); supported are Blender {SUPPORTED_TEXT}. "
        "Last lines of its output: SyntaxError: invalid syntax"
    )


def test_preflight_refuses_a_missing_executable(tmp_path):
    with pytest.raises(PreflightError, match="no such executable"):
        check_blender(str(tmp_path / "blender"))


def test_preflight_scene_is_a_face_on_cube():
    """The test scene's expected depth is what ray casting sees: 0.75 on a 20 x 20 block in the
    middle, background elsewhere."""
    vertices, faces, pose, depth = preflight_scene()
    hit = np.isfinite(depth)
    rows, cols = np.nonzero(hit)
    assert hit.sum() == 400 and (rows.min(), rows.max(), cols.min(), cols.max()) == (2, 21, 6, 25)
    assert np.all(depth[hit] == np.float32(0.75))
    cast = render_raycast(vertices, faces, pose, PREFLIGHT_CAMERA)[0]
    assert np.array_equal(np.isfinite(cast), hit)
    np.testing.assert_allclose(cast[hit], 0.75, atol=1e-6)
