"""The planners' settings: one dataclass each for the planner, its policies and the configs."""

from __future__ import annotations

from dataclasses import dataclass

from nbv.planning.information_gain import METRICS
from nbv.planning.occupancy import OccupancySettings
from nbv.utils.fields import at_least, check_ranges, one_of, setting

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


@dataclass(frozen=True)
class VolumetricSettings:
    """How the volumetric information-gain planner maps and scores (``ig:`` in
    ``conf/eval.yaml``).

    Attributes:
        resolution: voxel edge of the occupancy map, object units (the object fits in radius
            0.5, the cameras sit at distance 1).
        bound: the map covers the cube ``[-bound, bound]^3``, a whole number of voxels.
        columns: rays across a candidate's image (rows in proportion: 16 gives 16 x 12).
        metric: ``unobserved``, ``entropy``, ``rear_side_voxel``, ``rear_side_entropy``,
            ``frontier``, ``area_factor`` (Vasquez-Gomez et al.'s Area Factor) or
            ``proximity_count`` (Proximity Count) (:mod:`nbv.planning.information_gain`).
        depth: a ray's ``unobserved`` or ``frontier`` count stops at this many voxels, 0 for
            no cap: the count then weighs the unknown volume behind the surface a ray would
            meet, a cap weighs the surface.
        block: a captured view's rays that hit nothing are found in blocks of this many pixels
            (:func:`nbv.planning.occupancy.background_directions`).
        spread_weight: adds this times a candidate's smallest angle to the visited views (in
            units of 180 degrees) to its gain divided by the best candidate's gain: 0 ranks by
            gain alone.
    """

    resolution: float = 0.02
    bound: float = 0.56
    columns: int = setting(16, allows=at_least(1))
    metric: str = setting("unobserved", allows=one_of(METRICS))
    depth: int = setting(0, allows=at_least(0, note="voxels; 0: no cap"))
    block: int = setting(16, allows=at_least(1, note="pixels"))
    spread_weight: float = setting(0.0, check=lambda v: v >= 0, allowed=">= 0")

    def __post_init__(self) -> None:
        check_ranges(self)
        self.occupancy()  # the grid's rules (resolution, bound: keys of this group too)

    def occupancy(self) -> OccupancySettings:
        """The map's grid and sensor model."""
        return OccupancySettings(resolution=self.resolution, bound=self.bound)
