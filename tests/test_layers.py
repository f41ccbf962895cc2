"""The layers at run time: algorithms load neither storage, torch, Open3D nor Blender.

`make lint` checks the import graph statically (import-linter, contracts in pyproject.toml); this
checks what a fresh interpreter really loads, package ``__init__`` files included.
"""

import subprocess
import sys

import pytest

HEAVY = ("h5py", "torch", "open3d", "bpy")


@pytest.mark.parametrize(
    "module",
    [
        "nbv.geometry.scores",
        "nbv.dataset.records",
        "nbv.setcover.oneshot",
        "nbv.setcover.view_sets",
        "nbv.geometry.raycast",
        "nbv.geometry.fusion",
        "nbv.geometry.reconstruction_metrics",
        "nbv.policies.episode",
        "nbv.policies.registry",
        "nbv.eval.protocol",
    ],
)
@pytest.mark.slow
def test_algorithm_modules_load_no_heavy_dependency(module):
    code = f"import sys, {module}\nprint(','.join(m for m in {HEAVY!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"{module} loads {out.stdout.strip()}"


def test_the_dataset_entry_point_still_opens_lazily():
    code = (
        "import sys, nbv.dataset\n"
        "assert 'h5py' not in sys.modules\n"
        "nbv.dataset.open\n"
        "print('h5py' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"


@pytest.mark.parametrize(
    "module", ["nbv.models.config", "train.config", "nbv.eval.config", "nbv.dataset.config"]
)
@pytest.mark.slow
def test_settings_are_checked_without_torch(module):
    """A refused run answers before torch loads (seconds on a small machine)."""
    code = f"import sys, {module}\nprint('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
