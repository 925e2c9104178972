"""What the separability of the w-tests means for a block, in counts and words: how many
tested components are detectable but not separable (rho_max >= RHO_INSEPARABLE), which
components no other observation checks (r < R_MIN), named point by point, and what to do
(the advice form of `baarda plan`: more rays)."""

from __future__ import annotations

import numpy as np

from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.separability import RHO_INSEPARABLE
from baarda.quality.statistics import R_MIN, QualityResult

MAX_NAMED = 10  # points named in the summary (all of them in summary.json)


def _rays(model: AdjustedModel, points: set[str]) -> dict[str, int]:
    """Frames (photos, models) on which each of `points` has an active observation."""
    if not points:
        return {}
    pts = model.point[model.active].tolist()
    frs = model.frame[model.active].tolist()
    seen: dict[str, set] = {}
    for i in np.flatnonzero(np.fromiter(map(points.__contains__, pts), bool, len(pts))):
        if frs[i]:
            seen.setdefault(pts[i], set()).add(frs[i])
    return {p: len(s) for p, s in seen.items()}


def uncontrolled_by_point(model: AdjustedModel, q: QualityResult) -> list[dict]:
    """The active components that no other observation checks, grouped by point and
    component: [{"point", "component", "frames"}], in the order of the observations."""
    out: dict[tuple[str, str], list[str]] = {}
    for i in np.flatnonzero(q.active & ~q.controlled):
        key = (str(model.point[i]), str(model.component[i]))
        out.setdefault(key, []).append(str(model.frame[i]))
    return [{"point": p, "component": c, "frames": f} for (p, c), f in out.items()]


def separability_dict(model: AdjustedModel, q: QualityResult) -> dict:
    """summary.json's "separability": counts, shares and the uncontrolled components."""
    if q.rho_max is None:
        return {}
    tested = q.active & q.controlled
    nt, na = int(tested.sum()), int(q.active.sum())
    ins = int(np.sum(tested & (np.nan_to_num(q.rho_max) >= RHO_INSEPARABLE)))
    unc = int(np.sum(q.active & ~q.controlled))
    with np.errstate(invalid="ignore"):
        ratio = (q.msb / q.mdb)[tested]
    ratio = ratio[np.isfinite(ratio)]
    by_point = uncontrolled_by_point(model, q)
    insep_pts = {str(model.point[i]) for i in np.flatnonzero(
        tested & (np.nan_to_num(q.rho_max) >= RHO_INSEPARABLE))} - {""}
    named = (insep_pts | {u["point"] for u in by_point}) - {""}
    rays = _rays(model, named)
    weak = sorted(p for p in named if rays.get(p) == 2)
    return {
        "rho_inseparable": RHO_INSEPARABLE, "r_min": R_MIN, "tested": nt,
        "not_separable": ins, "share_not_separable": ins / nt if nt else float("nan"),
        "uncontrolled": unc, "share_uncontrolled": unc / na if na else float("nan"),
        "msb_over_mdb_median": float(np.median(ratio)) if len(ratio) else float("nan"),
        "uncontrolled_components": by_point, "two_ray_points": weak}


def separability_lines(d: dict, fk: str) -> list[str]:
    """The summary's lines from `separability_dict` (computed once per assessment: it
    walks every observation): the counts, the uncontrolled components in words, the advice;
    fk: the frame kind ("photo", "model")."""
    if not d or not d["tested"]:
        return []
    lines = [f"separability: {d['not_separable']} of {d['tested']} tested components "
             f"({100 * d['share_not_separable']:.1f} %) are detectable but not separable "
             f"(their w-test correlated with a neighbour's at |rho| >= {RHO_INSEPARABLE}: "
             "snooping can say that one of the two is wrong, not which); MSB/MDB median "
             f"{d['msb_over_mdb_median']:.2f}"]
    if d["uncontrolled"]:
        named = []
        shown = d["uncontrolled_components"][:MAX_NAMED]
        for u in shown:
            where = (f" on {fk}{'s' if len(u['frames']) > 1 else ''} {', '.join(u['frames'])}"
                     if u["frames"][0] else "")
            named.append(f"point {u['point']}: {u['component']}{where}")
        # the rest counted in components, as the total is (a group is a point's component on
        # one or more frames)
        more = d["uncontrolled"] - sum(len(u["frames"]) for u in shown)
        lines.append(f"uncontrolled: {d['uncontrolled']} active components "
                     f"({100 * d['share_uncontrolled']:.1f} %) cannot be checked (r < {R_MIN}): "
                     "an error there goes into the point unseen: "
                     + "; ".join(named) + (f"; and {more} more component(s)" if more > 0
                                           else ""))
    if d["two_ray_points"]:
        n = len(d["two_ray_points"])
        lines.append(f"advice: {n} point(s) seen on two {fk}s only carry these: measure them on "
                     f"a third {fk} (in the triple overlap of a strip or its neighbour) or plan "
                     "60 % side overlap or cross strips (baarda plan)")
    return lines
