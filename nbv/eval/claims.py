"""The paper's claims checked against the measured numbers, with the thresholds they use."""

from __future__ import annotations

import numpy as np

from nbv.eval.disturb import auc_changes
from nbv.eval.tables import fmt, groups
from nbv.eval.timing import timing_table
from nbv.policies.registry import (
    HULL_SCO,
    PCNBV,
    PCNBV_SPH,
    RANDOM,
)

#: Paper-claim thresholds (stated in the report).
CLOSE_AUC = 0.02


DEGRADE_FRACTION = 0.5


HOLD_FRACTION = 0.8


def _verdict(ok: bool | None) -> str:
    return "n/a (not measured)" if ok is None else ("**holds**" if ok else "**does not hold**")


def _yes(ok: bool) -> str:
    return "yes" if ok else "no"


def _dataset_claims(d: str, g: dict, times: dict, changes: list[dict]) -> list[str]:
    """The four claims on dataset ``d`` (see :func:`claims`)."""

    def auc(vs: str, m: str) -> float:
        s = g.get((d, vs, m, None))
        return s["auc"] if s else float("nan")

    def gain(vs: str, m: str) -> float:
        return auc(vs, m) - auc(vs, RANDOM.name)

    lines = []
    rnd = auc("original", RANDOM.name)
    beat = [m for m in (PCNBV.name, PCNBV_SPH.name, HULL_SCO.name) if (d, "original", m, None) in g]
    if beat and np.isfinite(rnd):
        ok = all(auc("original", m) > rnd for m in beat)
        nums = ", ".join(f"{m} {fmt(auc('original', m))}" for m in beat)
        lines.append(
            f"1. *Networks and convex-hull planner beat random* (AUC, original viewspace): "
            f"{nums} vs random {fmt(rnd)}: {_verdict(ok)}."
        )
    else:
        lines.append(f"1. *Networks and convex-hull planner beat random*: {_verdict(None)}.")

    nets = [m for m in (PCNBV.name, PCNBV_SPH.name) if (d, "permuted", m, None) in g]
    needed = [
        (d, vs, m, None) for vs in ("original", "permuted") for m in (HULL_SCO.name, RANDOM.name)
    ]
    if nets and all(k in g for k in needed):
        net_ok = all(gain("permuted", m) < DEGRADE_FRACTION * gain("original", m) for m in nets)
        hull_ok = gain("permuted", HULL_SCO.name) >= HOLD_FRACTION * gain("original", HULL_SCO.name)
        nums = "; ".join(
            f"{m} {fmt(gain('original', m))} -> {fmt(gain('permuted', m))}"
            for m in [*nets, HULL_SCO.name]
        )
        lines.append(
            "2. *On the permuted viewspace the networks degrade while the convex-hull planner "
            f"holds* (AUC above random, original -> permuted: {nums}; criterion: each network "
            f"keeps less than {DEGRADE_FRACTION:.0%} of its advantage, the planner at least "
            f"{HOLD_FRACTION:.0%}): {_verdict(net_ok and hull_ok)} (networks degrade: "
            f"{_yes(net_ok)}; planner holds: {_yes(hull_ok)})."
        )
    else:
        lines.append(f"2. *Permuted viewspace*: {_verdict(None)}.")

    if (d, "original", PCNBV.name, None) in g and (d, "original", PCNBV_SPH.name, None) in g:
        diff = auc("original", PCNBV_SPH.name) - auc("original", PCNBV.name)
        t_p, t_s = times[PCNBV.name]["total"], times[PCNBV_SPH.name]["total"]
        close, faster = abs(diff) <= CLOSE_AUC, t_s < t_p
        lines.append(
            f"3. *PCNBV-sph is close to PCNBV in AUC and faster*: AUC "
            f"{fmt(auc('original', PCNBV_SPH.name))} vs {fmt(auc('original', PCNBV.name))} "
            f"(difference {diff:+.3f}; close = within {CLOSE_AUC}), {t_s:.3f} s vs {t_p:.3f} s "
            f"per reconstruction (all runs): {_verdict(close and faster)} (close: "
            f"{_yes(close)}; faster: {_yes(faster)})."
        )
    else:
        lines.append(f"3. *PCNBV-sph close to PCNBV and faster*: {_verdict(None)}.")

    parts, oks = [], []
    for m in (PCNBV.name, PCNBV_SPH.name):
        c = {
            row["check"]: row["change"]
            for row in changes
            if row["method"] == m and row["dataset"] == d and row["viewspace"] == "original"
        }
        if "random_cloud" in c and "permuted_state" in c:
            oks.append(c["permuted_state"] < c["random_cloud"])
            parts.append(
                f"{m}: permuted state {c['permuted_state']:+.3f}, random cloud "
                f"{c['random_cloud']:+.3f}"
            )
    if oks:
        lines.append(
            "4. *The networks lean on the view state more than on the cloud* (AUC change, "
            f"original viewspace; {'; '.join(parts)}; criterion: the permuted state costs more "
            f"than the random cloud): {_verdict(all(oks))}."
        )
    else:
        lines.append(f"4. *Networks lean on the view state*: {_verdict(None)}.")
    return lines


def claims(evaluation) -> list[str]:
    """The paper's qualitative claims, per dataset, each with the measured numbers, the
    criterion and a verdict."""
    g = groups(evaluation.records)
    times = timing_table(evaluation.records)
    changes = auc_changes(evaluation.records)
    lines = []
    for d in [info.name for info in evaluation.datasets]:
        lines += [f"\n### {d}\n", *_dataset_claims(d, g, times, changes)]
    return lines
