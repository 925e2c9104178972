"""Pre-adjustment search for large errors and approximate values (FOTEF's 2D/3D pre-adjustment).

The models are connected one by one into a free block: the next model is the one with the
most points already determined; a similarity transformation (closed form, Umeyama 1991)
fits it to the current estimates of these points.  The connection is checked step by step:
while the largest discrepancy exceeds the threshold (FOTEF: 250 µm in x, y and 500 µm in z
at model scale), that point of the new model is set aside and the fit repeated, so the
large errors go first.  The free block is then fitted to the control (checked the same way,
with the threshold in the terrain; where the free connection has drifted more than that,
three times the robust RMS of the fit).  The transformations give the approximate values of
the rigorous adjustment; the set-aside observations enter it rejected, and iterative data
snooping restores those that prove innocent.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from baarda.errors import GeometryError
from baarda.independent import connect, similarity
from baarda.independent.model_problem import ModelProblem


@dataclass
class Finding:
    step: int
    kind: str  # 'connection' or 'control'
    model: str
    point: str
    discrepancy: list[float]  # connection: µm at model scale; control: m
    ratio: float  # discrepancy / threshold

    def to_dict(self) -> dict:
        return {"step": self.step, "kind": self.kind, "model": self.model, "point": self.point,
                "discrepancy": self.discrepancy, "ratio": self.ratio}

    def text(self) -> str:
        unit = "µm" if self.kind == "connection" else "m"
        d = ", ".join(f"{x:.4g}" for x in self.discrepancy)
        where = f"model {self.model} " if self.model else "control "
        return (f"{self.step:3d} {where}point {self.point}: ({d}) {unit}, "
                f"{self.ratio:.1f} x threshold")


@dataclass
class PreAdjustment:
    params: np.ndarray  # (nm, b) reduced terrain frame (as ModelProblem expects)
    pts: np.ndarray  # (np_used, d)
    obs_flag: np.ndarray  # (m_block, 3) bool: set aside by the search
    control_flag: np.ndarray  # (np_block, 3) bool
    findings: list[Finding] = field(default_factory=list)
    order: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        lines = [f"pre-adjustment search: {len(self.findings)} large error(s) set aside"]
        lines += ["  " + f.text() for f in self.findings]
        lines += [f"  note: {n}" for n in self.notes]
        return lines

    def summary(self) -> str:
        return "\n".join(self.lines())


class _Component:
    """A free sub-block: model transformations into its own frame and point estimates."""

    def __init__(self, npnt: int, dim: int):
        self.acc = np.zeros((npnt, dim))
        self.cnt = np.zeros(npnt)
        self.trans: dict[int, tuple] = {}

    def est(self, j):
        return self.acc[j] / self.cnt[j][:, None]

    def absorb(self, other: _Component, tr) -> None:
        """Add `other`, transformed by tr into this frame."""
        s, r, t = tr
        for m, (s2, r2, t2) in other.trans.items():
            self.trans[m] = (s * s2, r @ r2, t + s * r @ t2)
        self.acc += connect.apply(tr, other.acc / np.maximum(other.cnt, 1)[:, None]) * \
            other.cnt[:, None]
        self.cnt += other.cnt


def preadjust(problem: ModelProblem, thresholds_um: tuple[float, float] | None = None,
              search: bool = True) -> PreAdjustment:
    """Connect the models of `problem` (mode 3d or 2d), check connections and control."""
    bl, mode = problem.block, problem.mode
    if mode == "height":
        raise ValueError("the pre-adjustment works on the 3d or 2d adjustment")
    dim = problem.d
    thr_um = np.asarray(thresholds_um or bl.settings.pre_um, float)
    thr = (np.array([thr_um[0], thr_um[0], thr_um[1]]) * 1e-3)[problem.comps]  # mm
    if not search:
        thr = np.full(dim, np.inf)
    rows = problem.rows
    x = problem.obs
    pnt = problem.remap[bl.obs_point[rows]]
    frame = problem.frame
    npnt, nm = len(problem.point_ids), bl.n_models
    need = 3 if dim == 3 else 2
    by_model = [np.flatnonzero(frame == m) for m in range(nm)]
    by_point: list[list[int]] = [[] for _ in range(npnt)]
    for m, j in zip(frame, pnt, strict=True):
        by_point[j].append(m)
    flag = np.zeros(len(rows), bool)
    findings: list[Finding] = []
    notes: list[str] = []
    order: list[str] = []
    shared = np.array([sum(len(by_point[j]) > 1 for j in pnt[idx]) for idx in by_model])
    placed = np.zeros(nm, bool)
    comps: list[_Component] = []
    counter = [0]

    def place(comp: _Component, common, m: int, tr) -> None:
        idx = by_model[m][~flag[by_model[m]]]
        new = pnt[idx][comp.cnt[pnt[idx]] == 0]
        np.add.at(comp.acc, pnt[idx], connect.apply(tr, x[idx]))
        np.add.at(comp.cnt, pnt[idx], 1.0)
        for j in np.unique(new):
            for mm in by_point[j]:
                common[mm] += 1
        comp.trans[m] = tr
        placed[m] = True
        order.append(bl.models[m])

    while not placed.all():  # grow free sub-blocks model by model
        comp = _Component(npnt, dim)
        common = np.zeros(nm, np.int64)
        seed = int(np.argmax(np.where(placed, -1, shared)))
        place(comp, common, seed, (1.0, np.eye(dim), np.zeros(dim)))
        while True:
            cand = np.where(placed, -1, common)
            m = int(np.argmax(cand))
            if cand[m] < need:
                break
            idx = by_model[m]
            idx = idx[comp.cnt[pnt[idx]] > 0]

            def on_flag(k, disc, ratio, idx=idx, m=m):
                counter[0] += 1
                i = idx[k]
                findings.append(Finding(counter[0], "connection", bl.models[m],
                                        bl.points[problem.point_ids[pnt[i]]],
                                        [float(v) for v in -disc * 1e3], float(ratio)))
                flag[i] = True

            tr, use, bad = connect.check_fit(x[idx], comp.est(pnt[idx]), need, dim, thr, on_flag)
            if bad:
                notes.append(f"model {bl.models[m]}: connection has large discrepancies but "
                             f"only {need} points are left; not checked further")
            elif len(idx) == need and search:
                notes.append(f"model {bl.models[m]}: connected by {need} points only "
                             "(unchecked)")
            place(comp, common, m, tr)
        comps.append(comp)
    component = np.zeros(nm, int)  # sub-block of each model (locally consistent frames)
    for ci, comp in enumerate(comps):
        component[list(comp.trans)] = ci
    main = comps.pop(0)
    level_join = False
    while comps:  # join the sub-blocks through their common points
        ncommon = [int(np.sum((main.cnt > 0) & (c.cnt > 0))) for c in comps]
        k = int(np.argmax(ncommon))
        if ncommon[k] < need:
            left = sorted(bl.models[m] for c in comps for m in c.trans)
            raise GeometryError(f"model(s) {', '.join(left[:10])} share fewer than {need} "
                                "points with the connected block: the block is not connected")
        other = comps.pop(k)
        j = np.flatnonzero((main.cnt > 0) & (other.cnt > 0))

        def on_flag_join(kk, disc, ratio, j=j):
            counter[0] += 1
            findings.append(Finding(counter[0], "connection", "(sub-blocks)",
                                    bl.points[problem.point_ids[j[kk]]],
                                    [float(v) for v in -disc * 1e3], float(ratio)))

        tr = connect.check_join(other.est(j), main.est(j), need, dim, thr, on_flag_join)
        if dim == 3 and connect.collinear(main.est(j)):
            level_join = True
        main.absorb(other, tr)
    thr_final = np.array([thr[0], thr[1], np.inf]) if level_join else thr
    flag, findings = _final_check(problem, main, by_model, pnt, frame, x, flag, findings,
                                  thr_final, component)
    # points whose every row was set aside: estimate from all their rows
    lost = main.cnt == 0
    if lost.any():
        for m, tr in main.trans.items():
            idx = by_model[m][lost[pnt[by_model[m]]]]
            np.add.at(main.acc, pnt[idx], connect.apply(tr, x[idx]))
            np.add.at(main.cnt, pnt[idx], 1.0)
    local = main.est(np.arange(npnt))
    if level_join:
        notes.append("sub-blocks joined by points on a line (strips): their relative tilt is "
                     "not known before the adjustment, so the control heights are not checked")
        thr = np.array([thr[0], thr[1], np.inf])
    tc, cflag = _control_fit(problem, local, thr, findings, counter, notes)
    for k, f in enumerate(findings, 1):
        f.step = k
    params = np.zeros((nm, problem.b))
    for m, tr in main.trans.items():
        s, r, t = tr
        sc, rc, tcc = tc
        s_, r_, t_ = sc * s, rc @ r, tcc + sc * rc @ t
        c = problem.centroid[m, :dim]
        t_ = t_ - problem.origin[problem.comps]
        params[m] = (similarity.params3d(s_, r_, t_, c) if dim == 3
                     else similarity.params2d(s_, float(np.arctan2(r_[1, 0], r_[0, 0])), t_, c))
    pts = connect.apply(tc, local) - problem.origin[problem.comps]
    obs_flag = np.zeros((len(bl.obs_model), 3), bool)
    obs_flag[rows[flag][:, None], problem.comps[None, :]] = True
    return PreAdjustment(params, pts, obs_flag, cflag, findings, order, notes)


def _final_check(problem, main, by_model, pnt, frame, x, flag, findings, thr, component):
    """Points in three or more models of one sub-block: the row that disagrees with the
    others is the one in error (leave-one-out, largest first).  Connection findings of such
    points are replaced by this verdict.  Rows of different sub-blocks are not compared:
    a free connection drifts along a strip, so only locally connected models agree to the
    threshold.  A point in two models cannot tell which model is wrong (reported)."""
    bl = problem.block
    dim = x.shape[1]
    pos = np.empty((len(x), dim))
    for m, tr in main.trans.items():
        pos[by_model[m]] = connect.apply(tr, x[by_model[m]])
    key = pnt * (component.max() + 1) + component[frame]
    order = np.argsort(key, kind="stable")
    cuts = np.flatnonzero(np.diff(key[order])) + 1
    new_flag = flag.copy()
    verdicts = []
    judged = set()
    for r in np.split(order, cuts):
        if len(r) < 3:
            continue
        judged.add(int(pnt[r[0]]))
        use = np.ones(len(r), bool)
        while use.sum() >= 3:
            ru = r[use]
            d = pos[ru] - (pos[ru].sum(axis=0) - pos[ru]) / (len(ru) - 1)
            disc = np.array([connect.back(main.trans[frame[i]], d[k:k + 1])[0]
                             for k, i in enumerate(ru)])
            ratio = np.max(np.abs(disc) / thr, axis=1)
            w = int(np.argmax(ratio))
            if ratio[w] <= 1:
                break
            verdicts.append((ratio[w], ru[w], disc[w]))
            use[np.flatnonzero(use)[w]] = False
        new_flag[r] = ~use
    pid = problem.point_ids
    multi = {bl.points[pid[j]] for j in judged}
    kept = [f for f in findings if f.kind != "connection" or f.point not in multi]
    for f in kept:
        if f.kind == "connection" and f.model != "(sub-blocks)":
            f.model += " (or the other model of this point)"
    kept += [Finding(0, "connection", bl.models[frame[i]], bl.points[pid[pnt[i]]],
                     [float(v) for v in -dd * 1e3], float(ratio)) for ratio, i, dd in verdicts]
    kept.sort(key=lambda f: -f.ratio)  # the large errors first
    for k, f in enumerate(kept, 1):
        f.step = k
    return new_flag, kept


def _control_fit(problem: ModelProblem, local, thr_mm, findings, counter, notes):
    """Similarity local -> terrain from the control, checked step by step."""
    bl, dim = problem.block, problem.d
    ctrl = problem.control
    given = bl.xyz[ctrl][:, problem.comps]
    ok = (problem.wc_full > 0) & np.isfinite(given)
    loc = local[problem.remap[ctrl]]
    cflag = np.zeros((bl.n_points, 3), bool)
    while True:
        tr = connect.initial_control_fit(loc, given, ok, dim)
        if tr is None:
            raise GeometryError("the control does not fix the block (pre-adjustment: too few "
                                "control points for the similarity transformation)")
        res = np.where(ok, given - connect.apply(tr, loc), np.nan)
        thr_m = thr_mm * tr[0]  # local units are mm of the first model
        if dim == 3:
            groups = [(0, 1), (2,)]
        else:
            groups = [(0, 1)]
        size = np.column_stack([np.sqrt(np.nansum(res[:, list(g)] ** 2, axis=1))
                                / (thr_m[g[0]]) for g in groups])
        size = np.where(np.isnan(size), 0.0, size)
        # where the free block has drifted more than the threshold: 3 x robust RMS
        scale = np.ones(len(groups))
        for gi, g in enumerate(groups):
            a = np.abs(res[:, list(g)])
            if np.isfinite(a).any() and np.isfinite(thr_m[g[0]]):
                scale[gi] = max(1.0, 3 * 1.4826 * np.nanmedian(a) / thr_m[g[0]])
        ratio = size / scale
        worst = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        scale = scale[worst[1]]
        if ratio[worst] <= 1:
            break
        comps = list(groups[worst[1]])
        trial = ok.copy()
        trial[worst[0], comps] = False
        if connect.initial_control_fit(loc, given, trial, dim) is None or trial.sum() <= dim + 3:
            notes.append("control: large residuals remain but the control is too weak to "
                         "locate them; left to data snooping")
            break
        counter[0] += 1
        findings.append(Finding(counter[0], "control", "", bl.points[ctrl[worst[0]]],
                                [float(v) for v in res[worst[0], comps]],
                                float(ratio[worst] * scale)))
        ok = trial
        cflag[ctrl[worst[0]], problem.comps[comps]] = True
    return tr, cflag


def approximations(problem: ModelProblem) -> tuple[np.ndarray, np.ndarray]:
    """Approximate (params, points) for the rigorous adjustment (large errors left out)."""
    pre = preadjust(problem)
    return pre.params, pre.pts
