"""Similarity fits between model sets with step-by-step checks (the pre-adjustment's tools).

A transformation tr = (s, R, t) maps x -> t + s R x (3D or 2D).  Discrepancies are given
in the units of the source (model mm) and compared with per-component thresholds.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import combinations

import numpy as np

from baarda.adjustment.dense import DenseLeastSquares
from baarda.adjustment.solve import solve
from baarda.errors import GeometryError
from baarda.independent import similarity
from baarda.options import SolveOptions

Transform = tuple[float, np.ndarray, np.ndarray]  # (s, R, t): x -> t + s R x

# the rotations converge to 1e-12 rad; ten iterations at most (a start for the adjustment)
REFINE = SolveOptions(max_iterations=10, tolerance=1e-12, min_step=1e-3, final_step=True)


def collinear(dst: np.ndarray) -> bool:
    """True when the points lie (nearly) on one line."""
    sv = np.linalg.svd(dst - dst.mean(axis=0), compute_uv=False)
    return len(dst) < 3 or sv[1] <= 0.05 * sv[0]


def fit(src: np.ndarray, dst: np.ndarray, dim: int) -> Transform:
    """Similarity dst ~ t + s R src; in 3D a level fit (2D similarity and a height shift)
    when the points are nearly on one line, which leaves the roll about it free."""
    if dim == 3:
        if not collinear(dst):
            s, r, t = similarity.fit3d(src, dst)
        else:
            s, k, t2 = similarity.fit2d(src[:, :2], dst[:, :2])
            r = np.eye(3)
            r[:2, :2] = [[np.cos(k), -np.sin(k)], [np.sin(k), np.cos(k)]]
            t = np.append(t2, np.mean(dst[:, 2] - s * src[:, 2]))
    else:
        s, k, t = similarity.fit2d(src, dst)
        r = np.array([[np.cos(k), -np.sin(k)], [np.sin(k), np.cos(k)]])
    return s, r, t


def apply(tr: Transform, x: np.ndarray) -> np.ndarray:
    s, r, t = tr
    return t + s * x @ r.T


def back(tr: Transform, dx: np.ndarray) -> np.ndarray:
    """Discrepancies in the local frame -> model units."""
    s, r, _ = tr
    return dx @ r / s


def ratios(tr: Transform, src: np.ndarray, dst: np.ndarray, thr: np.ndarray):
    """Discrepancies (source units) and their largest ratio to the thresholds."""
    disc = back(tr, dst - apply(tr, src))
    return disc, np.max(np.abs(disc) / thr, axis=1)


def robust_start(src: np.ndarray, dst: np.ndarray, need: int, dim: int, thr: np.ndarray,
                 max_sets: int = 200) -> np.ndarray:
    """Inliers of the minimal-subset fit that agrees with the most points (several large
    errors in one connection cannot mask each other then)."""
    n = len(src)
    if n <= need + 1:
        return np.ones(n, bool)
    sets = list(combinations(range(n), need))
    if len(sets) > max_sets:
        pick = np.random.default_rng(0).choice(len(sets), max_sets, replace=False)
        sets = [sets[i] for i in pick]
    best, best_key = np.ones(n, bool), (-1, np.inf)
    c: list[int] | tuple[int, ...]
    for c in sets:
        c = list(c)
        if dim == 3 and collinear(dst[c]) and not collinear(dst):
            continue  # a level fit of three points on a line says little
        try:
            tr = fit(src[c], dst[c], dim)
        except (np.linalg.LinAlgError, ZeroDivisionError, FloatingPointError):
            continue
        if not np.isfinite(tr[0]) or tr[0] <= 0:
            continue
        _, ratio = ratios(tr, src, dst, thr)
        key = (int(np.sum(ratio <= 1)), float(np.median(ratio)))
        if key[0] > best_key[0] or (key[0] == best_key[0] and key[1] < best_key[1]):
            best, best_key = ratio <= 1, key
    if best.sum() < need:
        return np.ones(n, bool)
    return best


def check_fit(src: np.ndarray, dst: np.ndarray, need: int, dim: int, thr: np.ndarray,
              on_flag: Callable) -> tuple[Transform, np.ndarray, bool]:
    """Fit dst ~ tr(src); points that disagree are set aside, the largest first.

    A robust start (minimal subsets) finds the consistent points; the fit to them is then
    checked step by step.  A level fit (3D, points on a line) cannot check heights.
    """
    if dim == 3 and collinear(dst):
        thr = np.array([thr[0], thr[1], np.inf])
    use = robust_start(src, dst, need, dim, thr)
    if not use.all():
        tr = fit(src[use], dst[use], dim)
        disc, ratio = ratios(tr, src, dst, thr)
        out = np.flatnonzero(~use)
        for k in out[np.argsort(-ratio[out])]:
            on_flag(k, disc[k], ratio[k])
    while True:
        tr = fit(src[use], dst[use], dim)
        disc, ratio = ratios(tr, src[use], dst[use], thr)
        worst = int(np.argmax(ratio))
        if ratio[worst] <= 1 or use.sum() <= need:
            return tr, use, bool(ratio[worst] > 1)
        k = np.flatnonzero(use)[worst]
        on_flag(k, disc[worst], ratio[worst])
        use[k] = False


def check_join(src: np.ndarray, dst: np.ndarray, need: int, dim: int, thr: np.ndarray,
               on_flag: Callable, degree: int = 3) -> Transform:
    """Join two free sub-blocks.  Free connections drift smoothly along a strip, so the
    discrepancies of the join are tested after removing a polynomial (degree 3) in the
    position along the common points: only isolated disagreements are reported."""
    if dim == 3 and collinear(dst):
        thr = np.array([thr[0], thr[1], np.inf])
    use = robust_start(src, dst, need, dim, thr * 10)
    tr = fit(src[use], dst[use], dim)
    disc = back(tr, dst - apply(tr, src))
    c = dst - dst.mean(axis=0)
    axis = np.linalg.svd(c, full_matrices=False)[2][0]
    t = c @ axis
    t = t / max(np.abs(t).max(), 1e-12)
    deg = min(degree, max(len(t) - 4, 0))
    basis = np.vander(t, deg + 1)
    keep = np.ones(len(t), bool)
    while keep.sum() > deg + 2:
        coef, *_ = np.linalg.lstsq(basis[keep], disc[keep], rcond=None)
        res = disc - basis @ coef
        ratio = np.where(keep, np.max(np.abs(res) / thr, axis=1), 0.0)
        w = int(np.argmax(ratio))
        if ratio[w] <= 1:
            break
        on_flag(w, res[w], ratio[w])
        keep[w] = False
    return fit(src[keep & use], dst[keep & use], dim) if (keep & use).sum() >= need else tr


def initial_control_fit(loc: np.ndarray, given: np.ndarray, ok: np.ndarray,
                        dim: int) -> Transform | None:
    """(s, R, t) local -> terrain from the usable control components, or None."""
    plan = ok[:, 0] & ok[:, 1]
    if plan.sum() < 2 or np.ptp(given[plan, :2], axis=0).max() <= 0:
        return None
    if dim == 2:
        return fit(loc[plan], given[plan], 2)
    full = ok.all(axis=1)
    if full.sum() >= 3:
        p = given[full] - given[full].mean(axis=0)
        sv = np.linalg.svd(p, compute_uv=False)
        if sv[-2] > 1e-6 * sv[0]:
            return refine(fit(loc[full], given[full], 3), loc, given, ok)
    hz = ok[:, 2]
    if hz.sum() < 1:
        return None
    s, r2, t2 = fit(loc[plan, :2], given[plan, :2], 2)
    r = np.eye(3)
    r[:2, :2] = r2
    tz = np.mean(given[hz, 2] - s * loc[hz, 2])
    return refine((s, r, np.array([t2[0], t2[1], tz])), loc, given, ok)


def refine(tr: Transform, loc: np.ndarray, given: np.ndarray, ok: np.ndarray) -> Transform:
    """Least squares of the 7 parameters with every usable control component (unweighted)."""
    s, r, t = tr
    if not (np.isfinite(s) and s > 0 and np.isfinite(t).all()):
        raise GeometryError(f"the similarity of the models to the control has scale {s:.3g}: "
                            "model or control coordinates far too large or too small (check "
                            "their units)")
    p = similarity.params3d(s, r, t, np.zeros(3))
    if ok.sum() < 7:
        return tr
    zero = np.zeros((len(loc), 3))

    def func(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        xyz, jac = similarity.forward3d(np.tile(x, (len(loc), 1)), loc, zero)
        return xyz[ok], jac[ok]

    problem = DenseLeastSquares(func, given[ok], np.ones(int(ok.sum())), method="lstsq",
                                correction=lambda x, dx: float(np.max(np.abs(dx[3:6]))),
                                what="control fit")
    p = solve(problem, p, REFINE).state
    return 1.0 / p[6], similarity.rotation3d(p), p[:3]
