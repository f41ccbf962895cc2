"""``python -m nbv.plan``: plan views for a user's own object, from a mesh (a simulated episode)
or from real captures, and write the plan, its picture and its 3D page.

The planner a robot keeps warm is the library's, :class:`nbv.scan.planner.Planner`; it is also
importable from here (``from nbv.plan import Planner``), as it was before ``nbv.scan`` existed.
"""

__all__ = ["NextView", "Planner"]


def __getattr__(name: str):
    # Imported on first use: the planner pulls in the policies (and torch), which the command's
    # config checks and `python -m nbv.plan.example` do not need.
    if name in __all__:
        from nbv.scan import planner

        return getattr(planner, name)
    raise AttributeError(f"module 'nbv.plan' has no attribute {name!r}")
