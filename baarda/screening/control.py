"""Stage 3: control points checked by a spatial similarity transformation of each strip.

For every strip with three or more full (X, Y, Z) control points formed in stage 2, the
strip coordinates are transformed onto the given ground coordinates by a 7-parameter
similarity transformation

    X_ground = t + s R(omega, phi, kappa) (X_strip - c)      (c: centroid of the control)

Observations: the given control coordinates, sigma^2 = sigma_control^2 + s^2 var_strip, with
var_strip the variances of the strip coordinates from the strip adjustment, S-transformed to
the datum of the strip's control points (so that they do not depend on the strip's datum, the
first photo) and divided by diag(S) (exact for independent errors; strip_variances).
Control points are snooped as groups (all their coordinates together) with
baarda.quality.iterative, started from the full set and from every leave-one-out subset; a
rejected point is tested again by its predicted residual from the others and restored when
it fits.  The best run keeps the most points (then: global test
passed, smallest v^T P v).  A rejected point is removed only when the error is located: the
other points fit without it (no w-test rejects, with the sigmas scaled by the variance factor
of that fit when it exceeds 1: strip deformations are no error of a point), and no
leave-one-out subset that keeps it fits (otherwise another point could be the one in error: a
height error among four points is a single condition).  An error that is not located is left
to the bundle adjustment.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from baarda.block.photo_block import Block
from baarda.block.rotation import angles_from_matrix, rotation_and_derivatives
from baarda.errors import GeometryError
from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.iterative import SnoopingRun, iterative_snooping
from baarda.quality.statistics import analyse
from baarda.screening.fit import (
    Observations,
    SmallModel,
    largest_test,
    least_squares,
    small_model,
)
from baarda.screening.log import Entry, ScreeningLog
from baarda.screening.strips import Strip

XYZ = np.array(["X", "Y", "Z"], dtype=object)


def similarity(params: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t + s R d for d (n, 3) (centred strip coordinates) and its Jacobian (n, 3, 7)."""
    t, s = params[:3], params[3]
    r, dro, drp, drk = rotation_and_derivatives(params[4], params[5], params[6])
    rd = d @ r.T
    jac = np.empty((len(d), 3, 7))
    jac[:, :, :3] = np.eye(3)
    jac[:, :, 3] = rd
    for k, dr in enumerate((dro, drp, drk)):
        jac[:, :, 4 + k] = s * d @ dr.T
    return t + s * rd, jac


def s_transform(q: np.ndarray, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cofactors q (3n, 3n) of points xyz (n, 3) in the datum of these points (Baarda's
    S-transformation) and the diagonal of S.

    S q S^T with S = I - G (G^T G)^-1 G^T, G the 7 similarity directions (shifts, scale,
    rotations) at the points: the part that a similarity transformation absorbs is removed,
    so that the result no longer depends on where the strip's datum lies.  diag(S) is the
    share of an independent error of a coordinate that survives the transformation.
    """
    n = len(xyz)
    d = xyz - xyz.mean(axis=0)
    d = d / max(float(np.sqrt(np.mean(d**2))), 1e-12)
    g = np.zeros((n, 3, 7))
    g[:, :, :3] = np.eye(3)
    g[:, :, 3] = d
    g[:, 0, 5], g[:, 0, 6] = d[:, 2], -d[:, 1]
    g[:, 1, 4], g[:, 1, 6] = -d[:, 2], d[:, 0]
    g[:, 2, 4], g[:, 2, 5] = d[:, 1], -d[:, 0]
    g = g.reshape(3 * n, 7)
    s = np.eye(3 * n) - g @ np.linalg.solve(g.T @ g, g.T)
    return s @ q @ s.T, np.diag(s).copy()


def strip_variances(q: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """(n, 3) variances of strip coordinates for the similarity: diag(S q S^T) / diag(S).

    Exact for independent errors (q = s^2 I gives s^2); the datum part of q (errors a
    similarity transformation absorbs, large far from the strip's first photo) drops out.
    """
    qs, sd = s_transform(q, xyz)
    return (np.diag(qs) / np.maximum(sd, 1e-9)).reshape(-1, 3)


def closed_form(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Least-squares similarity dst = t + s R src (Umeyama 1991): parameters (7,)."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - ms, dst - md
    u, sv, vt = np.linalg.svd(b.T @ a)
    e = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    r = u @ e @ vt
    s = float(np.sum(sv * np.diag(e)) / np.sum(a**2))
    t = md - s * r @ ms
    return np.concatenate([t, [s], angles_from_matrix(r)])


@dataclass
class ControlCheck:
    """Stage 3 of one strip."""

    strip: str
    points: list[int]  # block indices of the control points used
    rejected: list[int]  # located errors: the only point whose removal makes the control fit
    unlocated: list[tuple[int, float, float, list[int]]]  # (point, w, critical, alternatives)
    params: np.ndarray  # t (3), s, omega, phi, kappa of the accepted fit (centred)
    sigma0: float
    run: SnoopingRun


class StripSimilarity:
    """The similarity transformation of one strip onto its control, as a small adjustment."""

    def __init__(self, block: Block, strip: Strip, points: list[int]):
        self.block, self.strip, self.points = block, strip, list(points)
        pts = block.points
        xs = np.array([strip.xyz[p] for p in points])
        self.centre = xs.mean(axis=0)
        self.d = xs - self.centre
        self.var = strip_variances(strip.covariance(points), xs)
        sig = pts.sigma[points]
        self.comp = np.isfinite(sig) & (pts.role[points] == "control")[:, None]
        j, k = np.nonzero(self.comp)
        self.j, self.k = j, k
        self.given = pts.xyz[points]
        ids = np.asarray(pts.ids, dtype=object)[points]
        full = self.comp.all(axis=1)
        self.params = closed_form(self.d[full], self.given[full])
        self.sig_c = sig[j, k]
        self.obs = Observations(self.given[j, k], self._sigma(self.params[3]),
                                np.full(len(j), "control", dtype=object), XYZ[k],
                                np.full(len(j), "", dtype=object), ids[j], j.astype(int))

    def _sigma(self, scale: float) -> np.ndarray:
        return np.sqrt(self.sig_c**2 + scale**2 * self.var[self.j, self.k])

    def func(self, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f, jac = similarity(params, self.d)
        return f[self.j, self.k], jac[self.j, self.k]

    def fit(self, active: np.ndarray, factors: np.ndarray | None = None,
            start: np.ndarray | None = None) -> SmallModel:
        """The similarity onto the `active` control, from the closed form of its full points
        (else from `start`, else the closed form of all points); its model's x = params."""
        active = np.asarray(active, bool)
        full = self.comp.all(axis=1) & np.array(
            [active[self.j == i].all() for i in range(len(self.points))])
        if full.sum() >= 3:
            start = closed_form(self.d[full], self.given[full])
        elif start is None:
            start = self.params
        sol = least_squares(self.func, start, self.obs, active, factors,
                            f"strip {self.strip.label} similarity")
        return small_model(sol.lin.a, self.obs, sol.lin.f, active, factors, problem=self,
                           x=sol.state)


def check_strip(block: Block, strip: Strip, *,
                tests: TestOptions = DEFAULT_TESTS) -> ControlCheck | None:
    """Snoop the control of one strip; None when it has fewer than 3 full control points."""
    pts = block.points
    ctrl = [p for p in sorted(strip.xyz) if pts.role[p] == "control"
            and np.isfinite(pts.sigma[p]).any()]
    full = [p for p in ctrl if np.isfinite(pts.sigma[p]).all()]
    if len(full) < 3:
        return None
    sim = StripSimilarity(block, strip, ctrl)
    n = sim.obs.n
    starts = [np.ones(n, bool)]
    if len(full) >= 4:
        starts += [sim.obs.group != j for j in range(len(ctrl)) if sim.comp[j].all()]
    best = None
    for start in starts:
        try:
            run = iterative_snooping(sim.fit(start), tests, by_group=True)
        except GeometryError:
            continue
        q = run.quality
        gt = q.global_test
        if q.redundancy < 1:  # nothing left to check the control with
            continue
        score = (int(np.sum(run.active)), bool(gt is None or gt.passed), -q.vtpv)
        if best is None or score > best[0]:
            best = (score, run, cast(SmallModel, run.model).x)
    if best is None:
        return None
    _, run, params = best
    rejected, unlocated = [], []
    for g in sorted({int(g) for g in sim.obs.group[~run.active]}):
        comps = np.flatnonzero(sim.obs.group == g)
        act = run.active.copy()
        act[comps] = True
        try:
            i, w, crit = largest_test(cast(SmallModel, run.model.refit(act)), comps, tests)
        except GeometryError:
            continue
        if not abs(w) > crit:  # rejected while other points were out: not an error of its own
            continue
        # located when the others fit without g and no other leave-one-out subset with g fits;
        # "fit" is judged with the variance factor of the fit without g (strip deformations
        # that the similarity cannot follow make it exceed 1: they are not errors of a point)
        others = [j for j in range(len(ctrl)) if j != g and sim.comp[j].all()
                  and run.active[sim.obs.group == j].all()]
        small = cast(SmallModel, run.model)
        base = _fit(small, run.active, tests)
        if base is None:
            continue
        factor = max(1.0, base.sigma0_hat) if base.redundancy > 0 else 1.0
        alt = [ctrl[j] for j in others
               if _fits(_fit(small, act & (sim.obs.group != j), tests), factor)]
        if _fits(base, factor) and not alt:
            rejected.append(ctrl[g])
        else:
            unlocated.append((ctrl[g], w, crit, alt))
    return ControlCheck(strip.label, ctrl, rejected, unlocated, params,
                        float(run.quality.sigma0_hat), run)


def _fit(model: SmallModel, active: np.ndarray, tests: TestOptions):
    """The statistics of the similarity with the `active` control, or None (singular)."""
    try:
        return analyse(model.refit(active), tests, separability=False)
    except GeometryError:
        return None


def _fits(q, factor: float) -> bool:
    """No w-test rejects when the sigmas are scaled by `factor` (and nothing contradicts a fit
    without redundancy)."""
    if q is None:
        return False
    if q.redundancy < 1:
        return True
    w = np.abs(np.nan_to_num(q.w[q.active & q.controlled]))
    return not np.any(w > q.k_w * factor)


def screen_control(block: Block, strips: list[Strip], log: ScreeningLog, *,
                   tests: TestOptions = DEFAULT_TESTS
                   ) -> tuple[set[int], list[ControlCheck]]:
    """Stage 3 for every strip; returns the control points found in error and the checks."""
    bad: set[int] = set()
    checks = []
    ids = block.points.ids
    for strip in strips:
        chk = check_strip(block, strip, tests=tests)
        if chk is None:
            log.note(3, f"strip {strip.label}", "fewer than three full control points formed "
                     "in the strip: control not checked")
            continue
        checks.append(chk)
        model = cast(SmallModel, chk.run.model)
        ctx = f"strip {strip.label} control ({len(chk.points)} points, sigma0 {chk.sigma0:.2f})"
        for p, w, crit, alt in chk.unlocated:
            why = (f"the control also fits without point(s) {', '.join(ids[a] for a in alt)}"
                   if alt else "the other control points do not fit either")
            log.add(Entry(3, ctx, "control", ids[p], action="kept", statistic="w", value=w,
                          critical=crit, reason=f"rejected, but not located ({why}): left to "
                          "the bundle adjustment"))
        for p in chk.rejected:
            rows = np.flatnonzero(model.point == ids[p])
            _, w, crit = largest_test(model, rows, tests)
            bad.add(p)
            log.add(Entry(3, ctx, "control", ids[p], statistic="w", value=w, critical=crit,
                          reason="disagrees with the strip transformed onto the other control "
                                 "points (predicted residual)"))
    return bad, checks
