"""A dataset model and its stored views written as capture folders, for the tests of the
planner on captures (``nbv.plan``, :class:`nbv.scan.Planner`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import open3d as o3d

import nbv.dataset
from nbv.assets.weights import shipped_weights
from nbv.dataset.generator import generate
from nbv.dataset.generator_settings import GeneratorSettings, Renderer, Synthetic
from nbv.geometry.camera import Intrinsics, project
from nbv.geometry.scores import DEFAULT_EPS
from nbv.infogain.settings import InfoGainSettings
from nbv.plan.config import PlanSettings
from nbv.policies.conditioned_network import ConditionedPolicy
from nbv.policies.episode import run_episode
from nbv.policies.method import MethodContext
from nbv.policies.registry import METHODS, NETWORK_INPUTS
from nbv.scan.method import policy_rng
from nbv.scan.planner import Planner
from nbv.scan.result import PlanResult
from nbv.scan.shipped import with_shipped
from nbv.setcover.settings import SetCoverSettings

CAMERA = Intrinsics.centred(64, 48, 48.0)
EPS = DEFAULT_EPS
START = 3


def capture_model(out: Path):
    """One synthetic model of the unseen categories, ray cast at 64 x 48 with 200 stored points a
    view, its original viewspace read (a :class:`nbv.dataset.records.ModelData`)."""
    summary = generate(
        GeneratorSettings(
            out_dir=out, synthetic=Synthetic({"train": 0, "valid": 0, "test": 0, "unseen": 1}),
            limit=1, intrinsics=CAMERA, n_gt=1000, eps=EPS, points_per_view=200,
            renderer=Renderer(backend="raycast"), progress=False,
        )
    )  # fmt: skip
    assert summary.produced == 1
    ds = nbv.dataset.open(out)
    return ds.model(ds.keys()[0], viewspaces=("original",))


def episode_views(model, method: str) -> list[int]:
    """The evaluator's episode: the registry's policy (a viewspace-conditioned network on the
    shipped weights, as the plan's default), the plan's generator."""
    networks = {}
    if NETWORK_INPUTS.get(method) == "directions":
        networks[method] = ConditionedPolicy.from_checkpoint(shipped_weights(method))
    ctx = with_shipped(
        MethodContext(networks, SetCoverSettings(), CAMERA, EPS, 10, InfoGainSettings())
    )
    policy = METHODS[method].build(ctx, policy_rng(0, method))
    return run_episode(model, "original", START, policy, 10).views


def depth_image(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """The sparse planar depth image whose back-projection gives ``points`` again (each stored
    point is a pixel centre's ray hit): (H, W) float64, inf elsewhere."""
    uv, z = project(points, CAMERA, pose)
    u, v = np.rint(uv).astype(int).T
    assert np.abs(uv - np.stack([u, v], axis=1)).max() < 1e-3
    depth = np.full((CAMERA.height, CAMERA.width), np.inf)
    depth[v, u] = z
    return depth


def write_folder(folder: Path, model, views: list[int], kind: str, scale=1.0, shift=None):
    """The dataset's stored views as a capture folder: PLY clouds or depth NPY images, with
    their poses (moved by ``scale`` and ``shift``)."""
    shift = np.zeros(3) if shift is None else shift
    folder.mkdir(parents=True)
    record = model.views["original"]
    entries = []
    for i, v in enumerate(views):
        points = record.view_points(v).astype(np.float64)
        pose = record.poses[v].copy()
        if kind == "ply":
            name = f"view_{i}.ply"
            cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points * scale + shift))
            assert o3d.io.write_point_cloud(str(folder / name), cloud)
        else:
            name = f"view_{i}.npy"
            np.save(folder / name, depth_image(points, pose) * scale)
        pose[:3, 3] = pose[:3, 3] * scale + shift
        entries.append({"file": name, "pose": pose.tolist()})
    k = CAMERA
    # Rendered views: their background is empty space, as the dataset's episode takes it.
    spec = {"intrinsics": dict(width=k.width, height=k.height, fx=k.fx, fy=k.fy, cx=k.cx,
                               cy=k.cy), "no_return": "free", "views": entries}  # fmt: skip
    (folder / "views.json").write_text(json.dumps(spec))
    return folder


def plan_captures(settings: PlanSettings) -> PlanResult:
    """What ``python -m nbv.plan captures=...`` plans: the folder loaded as the command loads it,
    then one decision."""
    return Planner.load(settings.captures, settings, views=settings.views).decide()
