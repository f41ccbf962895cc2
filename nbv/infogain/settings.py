"""The volumetric information-gain planner's settings (``infogain:`` in the configs)."""

from __future__ import annotations

from dataclasses import dataclass

from nbv.infogain.gain import METRICS
from nbv.infogain.occupancy import OccupancySettings
from nbv.utils.fields import at_least, check_ranges, one_of, setting


@dataclass(frozen=True)
class InfoGainSettings:
    """How the volumetric information-gain planner maps and scores (``infogain:`` in
    ``conf/eval.yaml``).

    Attributes:
        resolution: voxel edge of the occupancy map, object units (the object fits in radius
            0.5, the cameras sit at distance 1).
        bound: the map covers the cube ``[-bound, bound]^3``, a whole number of voxels.
        columns: rays across a candidate's image (rows in proportion: 16 gives 16 x 12).
        metric: ``unobserved``, ``entropy``, ``rear_side_voxel``, ``rear_side_entropy``,
            ``frontier``, ``area_factor`` (Vasquez-Gomez et al.'s Area Factor) or
            ``proximity_count`` (Proximity Count) (:mod:`nbv.infogain.gain`).
        depth: a ray's ``unobserved`` or ``frontier`` count stops at this many voxels, 0 for
            no cap: the count then weighs the unknown volume behind the surface a ray would
            meet, a cap weighs the surface.
        block: a captured view's rays that hit nothing are found in blocks of this many pixels
            (:func:`nbv.infogain.occupancy.background_directions`).
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
