"""The next view from a folder of captures (``python -m nbv.plan captures=...``), or a one-shot
planner's whole remaining plan: the captures read and checked
(:func:`nbv.plan.captures.read_captures`; ``views`` selects some), then one decision of a
:class:`nbv.plan.decision.Decider` on them, the same as :class:`nbv.plan.planner.Planner` makes
(the steps before the policy are :mod:`nbv.plan.placement`'s). The policy is the registry's, called
on the captured state (:func:`nbv.policies.episode.captured_state`), whose record says what each
view's missing pixels mean (:class:`nbv.policies.volumetric.SensedViews`).
"""

from __future__ import annotations

from nbv.plan.captures import read_captures, select_views
from nbv.plan.config import PlanSettings
from nbv.plan.decision import Decider
from nbv.plan.result import PlanResult


def plan_captures(settings: PlanSettings) -> PlanResult:
    """The next view (or a one-shot planner's remaining plan) from a folder of captures."""
    captures, given = read_captures(settings.captures)
    if settings.views is not None:
        captures = select_views(captures, settings.views, settings.captures)
    return Decider(settings, captures, given).decide()
