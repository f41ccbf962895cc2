"""The set cover's settings (``setcover:`` in the configs), shared by the plan, its policies and the
configs."""

from __future__ import annotations

from dataclasses import dataclass

from nbv.utils.fields import at_least, check_ranges, one_of, setting

#: View simulations of the planner: ``analytic`` (exact for a convex hull, fast) or ``raycast``
#: (renders the hull, about 100x slower).
SIMULATIONS = ("analytic", "raycast")


@dataclass(frozen=True)
class SetCoverSettings:
    """How the convex-hull set cover plans (``setcover:`` in ``conf/eval.yaml``).

    Attributes:
        n_samp: points drawn on the hull (the paper's 16384).
        simulation: ``analytic`` or ``raycast`` (see :mod:`nbv.setcover.view_sets`).
        dilate: with ``analytic``, also count the hull points within ``eps`` of a pixel's point
            just behind the silhouette or outside the image (:mod:`nbv.setcover.dilation`), as
            ``raycast`` does: closer to it, about 4x slower. Off by default.
        lmax: degree of the spherical signature of the ``sph`` variant.
        probes: random probe views taken first by the probing variant (they count in the
            episode).
        probe_points: points of each probe view added to the start view's cloud (the paper's
            "three random views with 100 points").
        network_views: views the VIG network of the two-stage planners
            (:mod:`nbv.policies.two_stage`) picks one at a time after the start view, before the
            set cover plans the rest on the hull of everything captured. 2 because the paper's
            Fig. 13 shows VIG nearly saturating after 2-3 views, and each network view is one
            view fewer for the set cover's plan.
    """

    n_samp: int = setting(16384, allows=at_least(1))
    simulation: str = setting("analytic", allows=one_of(SIMULATIONS))
    dilate: bool = False
    lmax: int = setting(3, allows=at_least(0))
    probes: int = setting(3, allows=at_least(0))
    probe_points: int = setting(100, allows=at_least(1))
    network_views: int = setting(2, allows=at_least(0))

    def __post_init__(self) -> None:
        check_ranges(self)
