"""Plan views for a user's own object: `python -m nbv.plan` from a mesh or from real captures."""
