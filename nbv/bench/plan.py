"""Benchmark rows of ``python -m nbv.plan``'s next-view decision from one 50k-point capture.

The capture is one full-resolution view of the benchmark's chair (640 x 480; an even 50,000 of
its points, or all of them when it has fewer), planned on the original viewspace with every point
kept (``points_per_view=0``), as ``python -m nbv.plan captures=...`` does after reading
the files: the state built, a fresh policy called (for ``ig`` the candidates' rays traced too, as
in a run's first decision). The references: for ``hull_sco``
the same plan with the ray-cast view simulation (the planner's exact slow path), for ``ig`` the
same decision in plain numpy (:func:`nbv.bench.infogain.plain_decision`).
"""

from __future__ import annotations

import numpy as np

from nbv.bench.infogain import plain_decision
from nbv.bench.timing import best_time
from nbv.geometry.scores import DEFAULT_EPS
from nbv.infogain.settings import InfoGainSettings
from nbv.policies.episode import EPISODE_VIEWS, captured_state
from nbv.policies.method import MethodContext
from nbv.policies.registry import HULL_SCO, IG, METHODS
from nbv.scan.shipped import with_shipped
from nbv.setcover.settings import SetCoverSettings
from nbv.utils.seeding import named_rng

#: Points of the benchmark's capture.
CAPTURE_POINTS = 50_000
#: The issue's target for one decision, seconds.
TARGET = 0.100


def capture(views: list[np.ndarray]) -> tuple[int, np.ndarray]:
    """The view with the most points and an even ``CAPTURE_POINTS`` of them: (view, (N, 3))."""
    v = int(np.argmax([len(p) for p in views]))
    points = views[v]
    if len(points) > CAPTURE_POINTS:
        points = points[np.linspace(0, len(points) - 1, CAPTURE_POINTS).astype(np.int64)]
    return v, points


def decide(method: str, view: int, points: np.ndarray, poses: np.ndarray, intrinsics,
           setcover: SetCoverSettings) -> int | list[int]:  # fmt: skip
    """One decision of ``method`` after the capture ``(view, points)``, as nbv.plan makes it
    (the chair is normalised already: its frame is the planners'), on the state nbv.plan
    builds (:func:`nbv.policies.episode.captured_state`)."""
    parts = [points if v == view else np.zeros((0, 3)) for v in range(len(poses))]
    state = captured_state(poses, parts, [view])
    ctx = with_shipped(
        MethodContext({}, setcover, intrinsics, DEFAULT_EPS, EPISODE_VIEWS, InfoGainSettings()),
        [method],
    )
    # The generator of nbv.scan.method.policy_rng.
    return METHODS[method].build(ctx, named_rng(0, "plan", method))(state)


def capture_rows(views: list[np.ndarray], poses: np.ndarray, intrinsics) -> list[dict]:
    """The rows: ``hull_sco`` and ``ig`` deciding from a 50k-point capture."""
    view, points = capture(views)
    # float32, as the plan's record holds them: the plain reference reads what the policy reads.
    points = points.astype(np.float32)
    analytic, raycast = SetCoverSettings(), SetCoverSettings(simulation="raycast")
    rows = []

    def hull_ours():
        return decide(HULL_SCO.name, view, points, poses, intrinsics, analytic)

    def hull_ref():
        return decide(HULL_SCO.name, view, points, poses, intrinsics, raycast)

    def ig_ours():
        return decide(IG.name, view, points, poses, intrinsics, analytic)

    def ig_ref():
        return plain_decision([(view, points)], poses, intrinsics, InfoGainSettings())

    for name, ours, ref, note in (
        (HULL_SCO.name, hull_ours, hull_ref, "analytic vs ray-cast view simulation"),
        (IG.name, ig_ours, ig_ref, "compiled vs plain numpy decision"),
    ):
        t_ours = best_time(ours, repeat=3, budget=10)
        t_ref = best_time(ref, repeat=2, budget=20)
        rows.append(dict(
            name=f"nbv.plan {name} decision, {len(points) // 1000}k-point capture",
            ours=t_ours, reference=t_ref, ratio=t_ref / t_ours, target=TARGET, note=note,
        ))  # fmt: skip
    return rows
