"""The convex-hull planner's settings: one dataclass for the planner, policies and configs."""

from __future__ import annotations

from dataclasses import dataclass

#: View simulations of the planner: ``analytic`` (exact for a convex hull, fast) or ``raycast``
#: (renders the hull, about 100x slower).
SIMULATIONS = ("analytic", "raycast")


@dataclass(frozen=True)
class PlannerSettings:
    """How the convex-hull set cover plans (``hull:`` in ``conf/eval.yaml``).

    Attributes:
        n_samp: points drawn on the hull (the paper's 16384).
        simulation: ``analytic`` or ``raycast`` (see :mod:`nbv.planning.view_sets`).
        dilate: with ``analytic``, also count the hull points within ``eps`` of a pixel's point
            just behind the silhouette or outside the image (:mod:`nbv.planning.dilation`), as
            ``raycast`` does: closer to it, about 4x slower. Off by default.
        lmax: degree of the spherical signature of the ``sph`` variant.
        probes: random probe views taken first by the probing variant (they count in the
            episode).
        probe_points: points of each probe view added to the start view's cloud (the paper's
            "three random views with 100 points").
    """

    n_samp: int = 16384
    simulation: str = "analytic"
    dilate: bool = False
    lmax: int = 3
    probes: int = 3
    probe_points: int = 100

    def __post_init__(self) -> None:
        checks = [
            ("n_samp", self.n_samp >= 1, "an integer >= 1"),
            ("simulation", self.simulation in SIMULATIONS, f"one of {', '.join(SIMULATIONS)}"),
            ("lmax", self.lmax >= 0, "an integer >= 0"),
            ("probes", self.probes >= 0, "an integer >= 0"),
            ("probe_points", self.probe_points >= 1, "an integer >= 1"),
        ]
        for key, ok, allowed in checks:
            if not ok:
                raise ValueError(f"hull.{key}={getattr(self, key)!r}: must be {allowed}")
