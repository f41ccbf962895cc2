"""The user's object frame and the planners' normalised frame, and the candidate cameras.

The planners were built for the dataset's frame: the object centred at the origin inside radius
0.5, Y up, cameras at distance 1 looking at the origin. A user's object has its own centre,
radius and up axis (a turntable's axis is often +z). :class:`ObjectFrame` maps between the two:

    normalised = s * M @ (world - center),   s = 0.5 / radius,   M = up_rotation(up)^T

(``M`` takes the rig's up axis to +y). Poses map with the same similarity: the rotation part is
turned by ``M``, the camera centre moves like a point; scaling changes no angle, so a camera's
intrinsics stay as they are.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from nbv.assets.meshes import NORMALISED_RADIUS
from nbv.geometry.camera import viewspace_poses
from nbv.geometry.viewspace_generators import up_rotation

if TYPE_CHECKING:
    from nbv.scan.settings import ScanSettings


@dataclass(frozen=True)
class ObjectFrame:
    """Where the object is in the user's world.

    Attributes:
        center: (3,) float64 centre of the object, world units.
        radius: radius of a sphere about ``center`` that holds the object, world units.
        up: the rig's up axis (a name of :data:`nbv.geometry.viewspace_generators.UP_AXES`).
    """

    center: np.ndarray
    radius: float
    up: str = "y"

    def __post_init__(self) -> None:
        center = np.asarray(self.center, dtype=np.float64)
        if center.shape != (3,) or not np.all(np.isfinite(center)):
            raise ValueError(f"object.center={center.tolist()}: must be 3 finite numbers")
        if not (np.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"object.radius={self.radius!r}: must be a positive distance")
        object.__setattr__(self, "center", center)

    @property
    def scale(self) -> float:
        """Normalised units per world unit."""
        return NORMALISED_RADIUS / float(self.radius)

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) rotation from the world to the normalised frame (the rig's up to +y)."""
        return up_rotation(self.up).T

    def points_to_normalised(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) world points -> (N, 3) float64 normalised points."""
        return self.scale * (np.asarray(points, dtype=np.float64) - self.center) @ self.rotation.T

    def points_to_world(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) normalised points -> (N, 3) float64 world points."""
        return np.asarray(points, dtype=np.float64) @ self.rotation / self.scale + self.center

    def poses_to_normalised(self, poses: np.ndarray) -> np.ndarray:
        """(..., 4, 4) camera-to-world poses in the world -> the same cameras, normalised."""
        poses = np.asarray(poses, dtype=np.float64)
        out = poses.copy()
        out[..., :3, :3] = self.rotation @ poses[..., :3, :3]
        out[..., :3, 3] = self.points_to_normalised(poses[..., :3, 3].reshape(-1, 3)).reshape(
            poses.shape[:-2] + (3,)
        )
        return out

    def poses_to_world(self, poses: np.ndarray) -> np.ndarray:
        """(..., 4, 4) normalised camera-to-world poses -> the same cameras in the world."""
        poses = np.asarray(poses, dtype=np.float64)
        out = poses.copy()
        out[..., :3, :3] = self.rotation.T @ poses[..., :3, :3]
        out[..., :3, 3] = self.points_to_world(poses[..., :3, 3].reshape(-1, 3)).reshape(
            poses.shape[:-2] + (3,)
        )
        return out


def candidate_poses(
    directions: np.ndarray, frame: ObjectFrame, distance: float | None
) -> np.ndarray:
    """Normalised camera-to-world poses of a viewspace placed around the object.

    Args:
        directions: (V, 3) unit directions from the object's centre, in the world frame (as
            :meth:`nbv.geometry.viewspace_generators.ViewspaceSpec.directions` gives them).
        frame: the object's frame.
        distance: the cameras' distance from the centre, world units; None = twice the
            object's radius (the dataset's ratio: distance 1 in the normalised frame).

    Returns:
        (V, 4, 4) float64 poses in the normalised frame, OpenCV axes, each looking at the
        origin with +y (the rig's up) up in the image, as the dataset's poses.
    """
    # Unit directions already: not normalised again, so that up=y leaves them bit for bit.
    normalised = np.asarray(directions, dtype=np.float64) @ frame.rotation.T
    # None keeps exactly 1.0: the same poses as the dataset's, bit for bit, for the default.
    reach = 1.0 if distance is None else float(distance) * frame.scale
    return viewspace_poses(normalised * reach)


def object_frame(settings: ScanSettings, center: np.ndarray, radius: float) -> ObjectFrame:
    """The object's frame: the ``object`` settings' centre and radius where given, else the
    region of interest's (``object.box_min`` / ``box_max``: its centre and half its diagonal),
    else the input's ``center`` (3,) and ``radius`` (world units: the mesh's, the captures' or
    estimated).

    Raises:
        ValueError: the cameras (``viewspace.radius``) would sit inside the object's sphere.
    """
    given = settings.object
    box = given.box_sphere
    if box is not None:
        center, radius = box
    c = given.center if given.center is not None else center
    r = given.radius if given.radius is not None else radius
    frame = ObjectFrame(np.asarray(c, dtype=np.float64), float(r), settings.viewspace.up)
    distance = settings.viewspace.radius
    if distance is not None and distance <= frame.radius:
        sphere = (f"object.radius={given.radius}" if given.radius is not None
                  else f"radius {frame.radius:.4g}")  # fmt: skip
        raise ValueError(
            f"viewspace.radius={distance}: the cameras would sit inside the object's sphere "
            f"({sphere})"
        )
    return frame
