"""Plan views for a user's own object: `python -m nbv.plan` from a mesh or from real captures,
and :class:`~nbv.plan.planner.Planner`, the same planner kept warm in a robot's loop."""

__all__ = ["NextView", "Planner"]


def __getattr__(name: str):
    # Imported on first use: the planner pulls in the policies (and torch), which the command's
    # config checks and `python -m nbv.plan.example` do not need.
    if name in __all__:
        from nbv.plan import planner

        return getattr(planner, name)
    raise AttributeError(f"module 'nbv.plan' has no attribute {name!r}")
