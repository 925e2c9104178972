"""A review session: the block as read, the operator's edits, and the adjustment with them
(docs/review.md).

Every edit is applied to the block as read through `edits.edited` (what `baarda adjust
--edits` applies): a rejection or restoration re-weights the prepared problem and adjusts
again from the solution before it (a component rejected stays in the observation vector,
predicted and tested, as data snooping leaves it); a re-measurement or a point set aside
prepares the edited block again, the adjustment warm-started.  The statistics are those of
`baarda adjust` without snooping (pipeline.assess).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np

from baarda.block.photo_block import Block
from baarda.options import Config
from baarda.quality.separability import RHO_INSEPARABLE
from baarda.review.edits import Edit, active_of, check, edited


@dataclass(frozen=True)
class State:
    """The adjustment of the block with the edits in force."""

    block: Block  # the edited block (re-measurements, points set aside)
    problem: object  # its BundleProblem (all components; `active` applied by reweighted)
    qc: object  # the Assessment
    seconds: float


def adjusted(block: Block, config: Config, edits: list[Edit], start=None,
             problem=None) -> State:
    """The Assessment of `block` with `edits` (what `baarda adjust --edits` writes):
    prepared as `baarda adjust` prepares it, the rejected components inactive.  start: the
    state to start from (a solution of the same problem, or None); problem: the prepared
    problem of the same edited block, to reuse."""
    from baarda.pipeline import assess, prepare

    t0 = time.perf_counter()
    block_e, rejected = edited(block, edits)
    if problem is None:
        problem = prepare(block_e, config=config)
    result = problem.reweighted(active_of(problem, rejected)).fit(start=start)
    return State(block_e, problem, assess(result, config.tests), time.perf_counter() - t0)


def _geometry_key(edits: list[Edit]) -> tuple:
    """What decides the prepared problem: the re-measurements and points set aside."""
    from baarda.review.edits import effective

    return tuple((e.action, e.photo, e.point, e.x, e.y) for e in effective(edits)
                 if e.action in ("remeasure", "aside"))


class ReviewSession:
    """The block under review: `summary()`, `observations()`, `edit()`; thread-safe (one
    edit at a time)."""

    def __init__(self, block: Block, config: Config):
        self.block, self.config = block, config
        self.edits: list[Edit] = []
        self.saved = 0  # edits written by the last save
        self.lock = threading.RLock()
        self.state = adjusted(block, config, [])
        self._key = _geometry_key([])

    # ------------------------------------------------------------ what the page shows
    def summary(self) -> dict:
        qc = self.state.qc
        res, q = qc.adjustment, qc.quality
        g = q.headline_test if q.headline_test is not None else q.global_test
        gt = None if g is None else {
            "statistic": float(g.statistic), "critical": float(g.critical),
            "alpha": float(g.alpha), "accepted": bool(g.passed)}
        act = np.asarray(q.active, bool)
        rows = self.rows()
        return {
            "name": self.block.settings.name,
            "photos": len(self.block.photos.ids), "points": len(self.block.points.ids),
            "observations": int(len(act)), "sigma0": float(res.sigma0),
            "redundancy": int(res.redundancy), "converged": bool(res.converged),
            "global_test": gt,
            "k_w": float(q.k_w), "rejected": int((~act).sum()),
            "significant": sum(r["verdict"] == "reject" for r in rows),
            "suspect": sum(r["verdict"] == "suspect" for r in rows),
            "inseparable": sum(r["partner"] is not None for r in rows),
            "edits": len(self.edits), "seconds": round(self.state.seconds, 3),
        }

    def rows(self) -> list[dict]:
        """Every observation component: kind, photo, point, component, w, mdb (µm for image,
        m for control), redundancy, rho_max, rho_partner, verdict (rejected: taken out by
        the operator; reject: |w| above critical; suspect: r < 0.001; accept)."""
        qc = self.state.qc
        m, q = qc.model, qc.quality
        kind, comp = np.asarray(m.kind), np.asarray(m.component)
        photo, point = np.asarray(m.frame), np.asarray(m.point)
        scale = np.where(kind == "image", 1e3, 1.0)
        w, r, mdb = np.asarray(q.w, float), np.asarray(q.redundancy_number, float), \
            np.asarray(q.mdb, float) * scale
        rho = np.full(len(w), np.nan) if q.rho_max is None else np.asarray(q.rho_max, float)
        partner = np.full(len(w), -1) if q.rho_partner is None else np.asarray(q.rho_partner)
        act = np.asarray(q.active, bool)
        out = []
        for n in range(len(w)):
            if not act[n]:
                v = "rejected"
            elif not r[n] >= 1e-3 or not math.isfinite(w[n]):
                v = "suspect"
            else:
                v = "reject" if abs(w[n]) > q.k_w else "accept"
            p = int(partner[n])
            twin = None
            if p >= 0 and math.isfinite(rho[n]) and rho[n] >= RHO_INSEPARABLE:
                twin = {"kind": str(kind[p]), "photo": _s(photo[p]), "point": _s(point[p]),
                        "component": str(comp[p])}
            out.append({"kind": str(kind[n]), "photo": _s(photo[n]), "point": _s(point[n]),
                        "component": str(comp[n]), "w": _f(w[n]), "mdb": _f(mdb[n]),
                        "redundancy": _f(r[n]), "rho_max": _f(rho[n]),
                        "rho_partner": twin, "partner": twin, "verdict": v,
                        "unit": "µm" if kind[n] == "image" else "m"})
        return out

    def observations(self, status: str = "flagged") -> list[dict]:
        """The rows to look at, worst first (rejected by the operator, significant,
        suspect, inseparable; by |w|), or every row ('all')."""
        rows = self.rows()
        if status == "flagged":
            rows = [r for r in rows if r["verdict"] != "accept" or r["partner"] is not None]
        order = {"rejected": 0, "reject": 1, "suspect": 3, "accept": 2}
        return sorted(rows, key=lambda r: (r["verdict"] == "suspect",
                                           -abs(r["w"]) if r["w"] is not None else 0.0,
                                           order[r["verdict"]]))

    def rays(self, point: str) -> list[dict]:
        """The rays of a point: photo, measured x, y (mm), residuals vx, vy (mm), the
        redundancy numbers, and the position predicted without the ray (x + vx / rx: exact
        for each component alone)."""
        qc = self.state.qc
        m, q = qc.model, qc.quality
        sel = np.flatnonzero((np.asarray(m.point) == point) & (np.asarray(m.kind) == "image"))
        xy = m.image_xy()
        by: dict[str, dict] = {}
        for n in sel:
            ph = _s(m.frame[n])
            d = by.setdefault(ph, {"photo": ph, "x": float(xy[n, 0]), "y": float(xy[n, 1])})
            c = str(m.component[n])
            v, r = float(m.residuals[n]), float(q.redundancy_number[n])
            d["v" + c] = v
            d["r" + c] = r
            d["w" + c] = _f(q.w[n])
            d["pred_" + c] = d[c] + v / r if r >= 1e-3 else None
            d["sigma_pred_" + c] = float(m.sigma[n] * math.sqrt(1 / r)) if r >= 1e-3 \
                else None
            d["active_" + c] = bool(q.active[n])
        return list(by.values())

    # ------------------------------------------------------------ edits
    def edit(self, body: dict) -> dict:
        """Apply one edit {action, photo, point, component, x_mm, y_mm}: {summary, changed:
        the components whose verdict changed, [{photo, point, component, before, after,
        w}]}.  ValueError for an edit that cannot apply (the session unchanged)."""
        e = _edit_of(body)
        with self.lock:
            if e.action == "undo" and not any(x.action != "undo" for x in
                                              _effective_list(self.edits)):
                raise ValueError("nothing to undo")
            if e.action != "undo":
                check(self.block, e)
            if e.action == "aside" and e.point in self._aside():
                raise ValueError(f"point {e.point} is set aside already")
            before = {_key(r): r["verdict"] for r in self.rows()}
            edits = self.edits + [e]
            key = _geometry_key(edits)
            same = key == self._key
            state = adjusted(self.block, self.config, edits,
                             start=self.state.qc.adjustment.state if same else None,
                             problem=self.state.problem if same else None)
            self.edits, self.state, self._key = edits, state, key
            rows = self.rows()
            changed = [{**{k: r[k] for k in ("kind", "photo", "point", "component", "w")},
                        "before": before.get(_key(r)), "after": r["verdict"]}
                       for r in rows if before.get(_key(r)) != r["verdict"]]
            return {"summary": self.summary(), "changed": changed}

    def _aside(self) -> set[str]:
        return {e.point for e in _effective_list(self.edits) if e.action == "aside"}


def _effective_list(edits):
    from baarda.review.edits import effective

    return effective(edits)


def _edit_of(body) -> Edit:
    """An Edit from a request's JSON object (ValueError: malformed)."""
    if not isinstance(body, dict):
        raise ValueError("the body must be a JSON object")
    action = body.get("action")
    if not isinstance(action, str):
        raise ValueError("'action' missing: reject, restore, remeasure, aside or undo")
    texts = {}
    for f in ("photo", "point", "component"):
        v = body.get(f, "")
        if not isinstance(v, str):
            raise ValueError(f"'{f}' must be a string")
        texts[f] = v
    xy = []
    for f in ("x_mm", "y_mm"):
        v = body.get(f)
        if v is None:
            xy.append(math.nan)
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            xy.append(float(v))
        else:
            raise ValueError(f"'{f}' must be a number (mm)")
    now = datetime.now(UTC).isoformat(timespec="seconds")
    return Edit(action, texts["photo"], texts["point"], texts["component"], *xy, now)


def _key(r: dict) -> tuple:
    return (r["kind"], r["photo"], r["point"], r["component"])


def _s(v) -> str:
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v)


def _f(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None
