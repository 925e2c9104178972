"""A review session: the block as read, the operator's edits, and the adjustment with them
(docs/review.md).

Every edit is applied to the block as read through `edits.edited` (what `baarda adjust
--edits` applies): a rejection or restoration re-weights the prepared problem and adjusts
again from the solution before it (a component rejected stays in the observation vector,
predicted and tested, as data snooping leaves it); a re-measurement prepares the edited
block again and is answered the same way; a point set aside (or back) prepares it again and
adjusts it from its approximations (start=None: the unknowns differ).  The statistics are those of
`baarda adjust` without snooping (pipeline.assess).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from typing import TYPE_CHECKING

import numpy as np

from baarda.block.photo_block import Block
from baarda.kinds import kind_of
from baarda.options import Config
from baarda.quality.separability import RHO_INSEPARABLE
from baarda.quality.statistics import R_MIN
from baarda.review.edits import Edit, active_of, check, edited, effective
from baarda.review.worker import SeparabilityWorker

if TYPE_CHECKING:
    from baarda.bundle.bundle_problem import BundleProblem
    from baarda.bundle.bundle_result import BundleResult
    from baarda.quality.assessment import Assessment


@dataclass(frozen=True)
class State:
    """The adjustment of the block with the edits in force."""

    block: Block  # the edited block (re-measurements, points set aside)
    problem: BundleProblem  # all components; `active` applied by reweighted
    qc: Assessment[BundleResult]
    seconds: float
    provisional: bool = False  # rho_max, rho_partner, msb still those of the state before


def adjusted(block: Block, config: Config, edits: list[Edit], start=None,
             problem=None, separability: bool = True,
             before: BundleResult | None = None) -> State:
    """The Assessment of `block` with `edits` (what `baarda adjust --edits` writes):
    prepared as `baarda adjust` prepares it, the rejected components inactive.  start: the
    state to start from (a solution of the same problem, or None); problem: the prepared
    problem of the same edited block, to reuse; separability: the w-test correlations
    (rho_max, its partner, the MSB) too (False: left None, `with_separability` adds them);
    before: the adjustment of the same problem with other components rejected, whose
    factorisation answers the re-weighting (review/reweight.py; a full adjustment from
    `start` where it does not converge)."""
    from baarda.pipeline import assess, prepare
    from baarda.review.reweight import refit

    t0 = time.perf_counter()
    block_e, rejected = edited(block, edits)
    if problem is None:
        problem = prepare(block_e, config=config)
    weighted = problem.reweighted(active_of(problem, rejected))
    result = refit(weighted, before) if before is not None else None
    if result is None:
        result = weighted.fit(start=start)
    qc = assess(result, config.tests, separability=separability)
    return State(block_e, problem, qc, time.perf_counter() - t0)


def _geometry_key(edits: list[Edit]) -> tuple:
    """What decides the prepared problem: the re-measurements and points set aside."""
    return tuple((e.action, e.photo, e.point, e.x, e.y) for e in effective(edits)
                 if e.action in ("remeasure", "aside"))


def _aside_key(edits: list[Edit]) -> tuple:
    """What decides the observation vector: the points set aside."""
    return tuple(sorted({e.point for e in effective(edits) if e.action == "aside"}))


class ReviewSession:
    """The block under review: `summary()`, `observations()`, `edit()`; thread-safe (one
    edit at a time)."""

    def __init__(self, block: Block, config: Config, edits: Sequence[Edit] = ()):
        """edits: those made before (a result folder's edits.csv), applied at once."""
        self.block, self.config = block, config
        self.edits: list[Edit] = list(edits)
        self.saved = len(self.edits)  # edits written by the last save
        self.lock = threading.RLock()
        self.state = adjusted(block, config, self.edits)
        self._rows: tuple = (None, [])
        self._later: tuple | None = None  # (state, the request of its w-test correlations)
        self._worker = SeparabilityWorker(block, config, self._separated)
        self._submitting: threading.Thread | None = None
        self._submit_lock = threading.Lock()
        import baarda.review.reweight  # noqa: F401  (imported here, not at the first edit)
        self._key = _geometry_key(self.edits)

    # ------------------------------------------------------------ what the page shows
    def summary(self) -> dict:
        qc = self.state.qc
        res, q = qc.adjustment, qc.quality
        g = q.headline_test if q.headline_test is not None else q.global_test
        gt = None if g is None else {
            "statistic": float(g.statistic), "critical": float(g.critical),
            "alpha": float(g.alpha), "accepted": bool(g.passed)}
        act = np.asarray(q.active, bool)
        verdict, twins = _verdicts(q)
        return {
            "name": self.block.settings.name,
            "photos": len(self.block.photos.ids), "points": len(self.block.points.ids),
            "observations": int(len(act)), "sigma0": float(res.sigma0),
            "redundancy": int(res.redundancy), "converged": bool(res.converged),
            "global_test": gt,
            "k_w": float(q.k_w), "rejected": int((~act).sum()),
            "significant": int((verdict == "reject").sum()),
            "suspect": int((verdict == "suspect").sum()),
            "inseparable": int(twins.sum()),
            "edits": len(self.edits), "seconds": round(self.state.seconds, 3),
            "separability": "updating" if self.state.provisional else "current",
        }

    def rows(self) -> list[dict]:
        """Every observation component: kind, photo, point, component, w, mdb (µm for image,
        m for control), redundancy, rho_max, rho_partner, verdict (rejected: taken out by
        the operator; reject: |w| above critical; suspect: r < 0.001; accept)."""
        return self._table().rows(range(self._table().n))

    def observations(self, status: str = "flagged") -> list[dict]:
        """The rows to look at, worst first (rejected by the operator, significant,
        suspect, inseparable; by |w|), or every row ('all'); only those rows are built."""
        t = self._table()
        keep = np.ones(t.n, bool) if status != "flagged" else \
            (t.verdict != "accept") | t.twins
        order = {"rejected": 0, "reject": 1, "suspect": 3, "accept": 2}
        rank = np.vectorize(order.__getitem__, otypes=[np.int64])(t.verdict) if t.n else \
            np.zeros(0, np.int64)
        absw = np.where(np.isfinite(t.w), np.abs(t.w), 0.0)
        idx = np.flatnonzero(keep)
        # (suspect last, |w| descending, verdict), stable: as sorted() on the dicts
        by = np.lexsort((rank[idx], -absw[idx], t.verdict[idx] == "suspect"))
        return t.rows(idx[by].tolist())

    def _table(self) -> _Table:
        """The observation table of the state (built once per state)."""
        if self._rows[0] is not self.state:
            self._rows = (self.state, _Table(self.state.qc))
        return self._rows[1]

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
            d["pred_" + c] = d[c] + v / r if r >= R_MIN else None
            d["sigma_pred_" + c] = float(m.sigma[n] * math.sqrt(1 / r)) if r >= R_MIN \
                else None
            d["active_" + c] = bool(q.active[n])
        return list(by.values())

    def block_map(self) -> dict:
        """The block in plan (the adjusted frame, m): {photos: [[id, X0, Y0]], points:
        [[id, X, Y]]} (points left out of the adjustment omitted)."""
        res = self.state.qc.adjustment
        blk = res.block
        eo, xyz = np.asarray(res.eo), np.asarray(res.points_xyz())
        photos = [[pid, float(e[0]), float(e[1])] for pid, e in zip(blk.photos.ids, eo,
                                                                     strict=True)]
        points = [[pid, float(p[0]), float(p[1])] for pid, p in zip(blk.points.ids, xyz,
                                                                     strict=True)
                  if np.isfinite(p[:2]).all()]
        return {"photos": photos, "points": points}

    # ------------------------------------------------------------ edits
    def edit(self, body: dict) -> dict:
        """Apply one edit {action, photo, point, component, x_mm, y_mm}: {summary, changed:
        the components whose verdict changed, [{photo, point, component, before, after,
        w}]}.  ValueError for an edit that cannot apply (the session unchanged)."""
        e = _edit_of(body)
        with self.lock:
            if e.action == "undo" and not any(x.action != "undo" for x in
                                              effective(self.edits)):
                raise ValueError("nothing to undo")
            if e.action != "undo":
                check(self.block, e)
            if e.action == "aside" and e.point in self._aside():
                raise ValueError(f"point {e.point} is set aside already")
            old = self.state
            edits = self.edits + [e]
            key = _geometry_key(edits)
            # the same observation vector (no point set aside or back): a rejection,
            # restoration or re-measurement is answered from the factorisation before it
            # (review/reweight.py) with the w-test correlations of the state before
            # (provisional); those of this state come from the worker process
            same = _aside_key(edits) == _aside_key(self.edits)
            problem = self.state.problem if key == self._key else None
            state = adjusted(self.block, self.config, edits,
                             start=self.state.qc.adjustment.state if same else None,
                             problem=problem, separability=not same,
                             before=self.state.qc.adjustment if same else None)
            if same:
                prev = self.state.qc.quality
                state = replace(state, qc=replace(state.qc, quality=replace(
                    state.qc.quality, rho_max=prev.rho_max, rho_partner=prev.rho_partner,
                    msb=prev.msb)), provisional=True)
            self.edits, self.state, self._key = edits, state, key
            if same:
                self._separability(state)
            return {"summary": self.summary(), "changed": _changed(old, state, same)}

    def _separability(self, state: State) -> None:
        """The w-test correlations of `state` asked of the session's worker process
        (review/worker.py), put in place when they come if it is still the state.  Asked
        from a thread: starting the process (a new interpreter) takes longer than the
        edit."""
        edits = list(self.edits)

        def submit() -> None:
            with self._submit_lock:
                self._later = (state, self._worker.request(edits))

        self._submitting = threading.Thread(target=submit, daemon=True)
        self._submitting.start()

    def _separated(self, n: int, result) -> None:
        """The worker's answer to request n: (rho_max, rho_partner, msb), or None."""
        with self.lock:
            later = self._later
            if result is None or later is None or later[1] != n:
                return
            state = later[0]
            if self.state is state and state.provisional:
                rho, partner, msb = result
                q = replace(state.qc.quality, rho_max=rho, rho_partner=partner, msb=msb)
                self.state = replace(state, qc=replace(state.qc, quality=q),
                                     provisional=False)

    def settle(self, timeout: float | None = None) -> None:
        """Wait until the state's w-test correlations are its own (not provisional); where
        the worker failed, computed here."""
        from baarda.quality.statistics import with_separability

        if self._submitting is not None:
            self._submitting.join(timeout)
        later = self._later
        if later is None:
            return
        state, n = later
        if not self._worker.wait(n, timeout):
            return
        with self.lock:
            if self.state is state and state.provisional:
                bare = replace(state.qc.quality, rho_max=None, rho_partner=None, msb=None)
                q = with_separability(state.qc.model, bare)
                self.state = replace(state, qc=replace(state.qc, quality=q),
                                     provisional=False)

    def close(self) -> None:
        """End the worker process (a computation under way is dropped)."""
        if self._submitting is not None:
            self._submitting.join(60)
        self._worker.close()

    def _aside(self) -> set[str]:
        return {e.point for e in effective(self.edits) if e.action == "aside"}


class _Table:
    """The observation components of an Assessment as columns; `rows(idx)` the dicts of
    the rows the page asks for (building all of a large block's took a fifth of a second)."""

    def __init__(self, qc):
        m, q = qc.model, qc.quality
        self.kind = np.asarray(m.kind).astype(str)
        self.comp = np.asarray(m.component).astype(str)
        self.photo = [_s(v) for v in np.asarray(m.frame).tolist()]
        self.point = [_s(v) for v in np.asarray(m.point).tolist()]
        self.w = np.asarray(q.w, float)
        self.n = n = len(self.w)
        self.r = np.asarray(q.redundancy_number, float)
        # each kind's MDB in its Kind's unit (image µm, control m, IMU thousandths of the
        # project's angle unit)
        angle_unit = qc.adjustment.block.settings.angle_unit
        factor, self.unit = np.ones(n), np.full(n, "", dtype=object)
        for name in np.unique(self.kind).tolist():
            f, unit = kind_of(name).shown(angle_unit)
            at = self.kind == name
            factor[at], self.unit[at] = f, unit
        self.mdb = np.asarray(q.mdb, float) * factor
        self.rho = np.full(n, np.nan) if q.rho_max is None else np.asarray(q.rho_max, float)
        self.partner = np.full(n, -1) if q.rho_partner is None else \
            np.asarray(q.rho_partner, int)
        self.verdict, self.twins = _verdicts(q)

    def rows(self, idx) -> list[dict]:
        out = []
        kind, comp, photo, point = self.kind, self.comp, self.photo, self.point
        idx = np.asarray(list(idx), np.int64)
        w, mdb, r, rho = (_list(a[idx]) for a in (self.w, self.mdb, self.r, self.rho))
        for i, k in enumerate(idx.tolist()):
            twin = None
            if self.twins[k]:
                p = int(self.partner[k])
                twin = {"kind": str(kind[p]), "photo": photo[p], "point": point[p],
                        "component": str(comp[p])}
            out.append({"kind": str(kind[k]), "photo": photo[k], "point": point[k],
                        "component": str(comp[k]), "w": w[i], "mdb": mdb[i],
                        "redundancy": r[i], "rho_max": rho[i], "rho_partner": twin,
                        "verdict": str(self.verdict[k]), "unit": str(self.unit[k])})
        return out


def _verdicts(q) -> tuple[np.ndarray, np.ndarray]:
    """(the verdict of every component: rejected, suspect, reject or accept; whether it has
    a partner it cannot be told from, |rho| >= RHO_INSEPARABLE)."""
    w = np.asarray(q.w, float)
    act = np.asarray(q.active, bool)
    # an active component is controlled where r >= R_MIN; flagged: active, controlled and
    # |w| > k (quality/statistics.py)
    tested = np.asarray(q.controlled, bool) & np.isfinite(w)
    verdict = np.where(~act, "rejected", np.where(~tested, "suspect", np.where(
        np.asarray(q.flagged, bool), "reject", "accept")))
    if q.rho_max is None:
        return verdict, np.zeros(len(w), bool)
    twins = (np.asarray(q.rho_partner) >= 0) & \
        (np.nan_to_num(np.asarray(q.rho_max, float)) >= RHO_INSEPARABLE)
    return verdict, twins


def _labels(qc) -> list[tuple]:
    m = qc.model
    return list(zip(np.asarray(m.kind).astype(str).tolist(),
                    [_s(v) for v in np.asarray(m.frame).tolist()],
                    [_s(v) for v in np.asarray(m.point).tolist()],
                    np.asarray(m.component).astype(str).tolist(), strict=True))


def _changed(old: State, new: State, same: bool) -> list[dict]:
    """The components whose verdict differs between two states: [{kind, photo, point,
    component, w, before, after}] (same: the same observation vector, compared by index)."""
    v_old, _ = _verdicts(old.qc.quality)
    v_new, _ = _verdicts(new.qc.quality)
    w = np.asarray(new.qc.quality.w, float)
    new_labels = None
    if same:
        at = np.flatnonzero(v_old != v_new)
        before = v_old[at].tolist()
    else:
        new_labels = _labels(new.qc)
        was = dict(zip(_labels(old.qc), v_old.tolist(), strict=True))
        before = [was.get(k) for k in new_labels]
        at = np.flatnonzero([b != v for b, v in zip(before, v_new.tolist(), strict=True)])
        before = [before[k] for k in at]
    m = new.qc.model
    out = []
    for k, b in zip(at.tolist(), before, strict=True):
        lab = new_labels[k] if new_labels is not None else (
            str(m.kind[k]), _s(m.frame[k]), _s(m.point[k]), str(m.component[k]))
        out.append({"kind": lab[0], "photo": lab[1], "point": lab[2], "component": lab[3],
                    "w": _f(w[k]), "before": b, "after": str(v_new[k])})
    return out


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
    return Edit(action, texts["photo"], texts["point"], texts["component"], xy[0], xy[1], now)


def _s(v) -> str:
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v)


def _list(a: np.ndarray) -> list:
    """The values of a float array, None where not finite (JSON has no NaN)."""
    return [float(v) if np.isfinite(v) else None for v in np.asarray(a, float)]


def _f(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None
