"""The robot's planning library: next views from captured depth views, one decision at a time.

``from nbv.scan import Planner``: :class:`~nbv.scan.planner.Planner` keeps the settings, the
object's frame, the candidates and the policy warm between decisions. Below it:

* :mod:`~nbv.scan.settings`: :class:`~nbv.scan.settings.ScanSettings`, plain frozen dataclasses
  (no hydra);
* :mod:`~nbv.scan.capture`: a captured view (:class:`~nbv.scan.capture.Capture`) from a depth
  image or a cloud; :mod:`~nbv.scan.captures`: the capture folder's format, its reader and
  writer;
* :mod:`~nbv.scan.object_estimate`, :mod:`~nbv.scan.frame`, :mod:`~nbv.scan.candidates`,
  :mod:`~nbv.scan.placement`: the object found or declared, its frame, the candidate poses and
  the limits of where the camera may go;
* :mod:`~nbv.scan.method`, :mod:`~nbv.scan.decision`: the registry's policy built for a scan,
  and the decision on the views so far (:class:`~nbv.scan.result.PlanResult`);
* :mod:`~nbv.scan.reconstruction`: the depth views fused into a mesh.
* :mod:`~nbv.scan.shipped`: the weights the package ships, given to the methods: a network
  method's checkpoint or shipped weights, the shipped completion network and learned score.

``python -m nbv.plan`` (:mod:`nbv.plan`) is the command on top: it reads a folder or simulates a
mesh's episode, and writes the plan's files, picture and page.

Third-party imports: numpy, open3d, OpenEXR, PIL.
"""

__all__ = ["NextView", "Planner", "ScanSettings"]


def __getattr__(name: str):
    # Imported on first use: the planner pulls in the policies (and torch).
    if name in ("NextView", "Planner"):
        from nbv.scan import planner

        return getattr(planner, name)
    if name == "ScanSettings":
        from nbv.scan.settings import ScanSettings

        return ScanSettings
    raise AttributeError(f"module 'nbv.scan' has no attribute {name!r}")
