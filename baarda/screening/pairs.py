"""Stage 1: planimetric 2D transformations between the image coordinates of photo pairs.

For every pair of overlapping photos (within and across strips) the image coordinates of the
common points on photo b are fitted to those on photo a by a similarity (4 parameters) or
an affine (6) transformation, with iterative data snooping of whole points.  The model is a
simplification (relief displacement, tilts), so its variance is not known: each pair is first
snooped with its own variance factor (Pope's tau), and the median of the pairs' standard
deviations is then the a-priori sigma of the w-test with which every pair is snooped (alpha
1e-4).  A rejected point is removed only when its estimated error exceeds both the parallax
that the relief of the control heights can cause between the two photos and the critical w
times the pooled sigma: the stage is meant for errors that stand out far above what the 2D
model cannot follow: identification, numbering and other large blunders.

A point that is inconsistent in a pair may be in error on either photo.  It is blamed on the
photo that two or more tested pairs contain and all of them reject (and that is in every
rejecting pair); when no single photo is singled out (a point on two photos only, or rejected
in one pair only), it is removed from every photo of the rejecting pairs if the error is gross
(more than GROSS times the tolerance: it would upset the relative orientations of stage 2),
and otherwise left to stage 2, which can locate it with a third ray.

Transformations, photo b = T(photo a), image coordinates in mm:
    similarity  x' = a x - b y + c,   y' = b x + a y + d
    affine      x' = a1 x + a2 y + a3,  y' = b1 x + b2 y + b3
    projective  x' = (a1 x + a2 y + a3) / (c1 x + c2 y + 1),  y' = (b1 x + b2 y + b3) / (...)
The projective one maps a plane exactly from one photo to the other, so the tilts of the
photos leave no model error, only the relief does; it is used where the pair has enough
points (auto), the affine and the similarity where it has fewer.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from baarda.block.photo_block import Block
from baarda.errors import GeometryError
from baarda.options import TestOptions
from baarda.quality.distributions import b_method
from baarda.quality.iterative import SnoopingRun, iterative_snooping
from baarda.quality.statistics import analyse
from baarda.screening.fit import Observations, SmallProblem
from baarda.screening.log import Entry, ScreeningLog

N_PARAMS = {"similarity": 4, "affine": 6, "projective": 8}
# the 2D model is approximate, so only clear errors count: alpha0 1e-4
PAIR_TESTS = TestOptions(1e-4, 0.80)


def design(xy: np.ndarray, kind: str) -> np.ndarray:
    """A (2n, u) of the transformation of points xy (n, 2); rows x0, y0, x1, y1, ..."""
    n = len(xy)
    x, y = xy[:, 0], xy[:, 1]
    one, zero = np.ones(n), np.zeros(n)
    if kind == "similarity":
        rx = np.column_stack([x, -y, one, zero])
        ry = np.column_stack([y, x, zero, one])
    elif kind == "affine":
        rx = np.column_stack([x, y, one, zero, zero, zero])
        ry = np.column_stack([zero, zero, zero, x, y, one])
    else:
        raise ValueError(f"unknown 2D transformation '{kind}' (similarity or affine)")
    a = np.empty((2 * n, rx.shape[1]))
    a[0::2], a[1::2] = rx, ry
    return a


def transformation(xy: np.ndarray, kind: str):
    """f(params) -> (values (2n,), Jacobian (2n, u)) of the transformation of xy, and a start."""
    if kind != "projective":
        a = design(xy, kind)
        return (lambda p: (a @ p, a)), np.zeros(a.shape[1])
    x, y = xy[:, 0], xy[:, 1]
    n = len(xy)

    def f(p):
        den = p[6] * x + p[7] * y + 1.0
        u = p[0] * x + p[1] * y + p[2]
        v = p[3] * x + p[4] * y + p[5]
        out = np.empty(2 * n)
        out[0::2], out[1::2] = u / den, v / den
        jac = np.zeros((2 * n, 8))
        jac[0::2, 0:3] = np.column_stack([x, y, np.ones(n)]) / den[:, None]
        jac[1::2, 3:6] = np.column_stack([x, y, np.ones(n)]) / den[:, None]
        jac[0::2, 6], jac[0::2, 7] = -u * x / den**2, -u * y / den**2
        jac[1::2, 6], jac[1::2, 7] = -v * x / den**2, -v * y / den**2
        return out, jac

    return f, np.array([1.0, 0, 0, 0, 1.0, 0, 0, 0])


def choose_kind(n_points: int, kind: str, min_redundancy: int) -> str | None:
    """The transformation to use for a pair with n common points, or None (too few).

    auto: projective where it leaves a redundancy of 6 or more, else affine (likewise), else
    similarity (with at least `min_redundancy`).
    """
    if kind == "auto":
        for k in ("projective", "affine"):
            if 2 * n_points - N_PARAMS[k] >= max(min_redundancy, 6):
                return k
        kind = "similarity"
    if kind not in N_PARAMS:
        raise ValueError(f"unknown 2D transformation '{kind}' (similarity, affine, projective)")
    return kind if 2 * n_points - N_PARAMS[kind] >= min_redundancy else None


@dataclass
class PairTest:
    """Snooping of one photo pair (photo indices a < b)."""

    a: int
    b: int
    kind: str
    points: np.ndarray  # block point indices of the common points
    tested: np.ndarray  # (k,) bool: point's test is controlled
    rejected: np.ndarray  # (k,) bool
    value: np.ndarray  # (k,) largest |test statistic| of the point (rejected: when predicted)
    size: np.ndarray  # (k,) estimated error of a rejected point (its predicted residual), mm
    critical: float
    tolerance: float  # mm: errors up to this size were not counted as rejected
    sigma0: float
    redundancy: int
    run: SnoopingRun | None = field(default=None, repr=False)


GROSS = 4.0  # a point one pair rejects is removed (from both photos) only above GROSS * tolerance


def common_points(block: Block, keep: np.ndarray, min_points: int) -> list[tuple]:
    """Pairs (a, b, rows on a, rows on b) of photos with at least min_points common points."""
    im = block.image
    rows = np.flatnonzero(keep)
    # first row of every (photo, point): twin rays of stereo mode count once
    key = im.photo[rows] * len(block.points) + im.point[rows]
    _, first = np.unique(key, return_index=True)
    rows = rows[first]
    inc = sp.csr_matrix((np.ones(len(rows)), (im.photo[rows], im.point[rows])),
                        shape=(len(block.photos), len(block.points)))
    counts = sp.triu(inc @ inc.T, k=1).tocoo()
    row_of = {(int(im.photo[r]), int(im.point[r])): int(r) for r in rows}
    out = []
    for a, b, c in zip(counts.row, counts.col, counts.data, strict=True):
        if c < min_points:
            continue
        pa = set(im.point[rows[im.photo[rows] == a]].tolist())
        pts = np.array(sorted(pa & set(im.point[rows[im.photo[rows] == b]].tolist())))
        out.append((int(a), int(b), np.array([row_of[(int(a), p)] for p in pts]),
                    np.array([row_of[(int(b), p)] for p in pts])))
    return out


def fit_pair(block: Block, a: int, b: int, rows_a: np.ndarray, rows_b: np.ndarray, kind: str,
             *, tests: TestOptions, statistic: str = "tau",
             sigma_mm: float | None = None, tolerance_mm: float = 0.0) -> PairTest | None:
    """Fit photo b's coordinates to photo a's by `kind`, snooping whole points.

    sigma_mm: a-priori standard deviation of the coordinate differences (None: from the
    image sigmas of both photos).  A point counts as rejected when the snooping rejects it and
    the part of its error it would show in the fit (redundancy number times the predicted
    residual) exceeds `tolerance_mm` and, for the w-test, the critical w times the pair's own
    standard deviation after the rejections (a pair the 2D model fits worse than the others
    keeps its points).  `size` reports the estimated error itself (the predicted residual).
    None when the transformation cannot be fitted at all.
    """
    im = block.image
    pts = im.point[rows_a]
    k = len(pts)
    xy_a, xy_b = im.xy_mm[rows_a], im.xy_mm[rows_b]
    sig = np.hypot(im.sigma_xy[rows_a], im.sigma_xy[rows_b]).ravel()
    if sigma_mm is not None:
        sig = np.full(2 * k, float(sigma_mm))
    pid = np.asarray(block.points.ids, dtype=object)[pts]
    obs = Observations(xy_b.ravel(), sig, np.full(2 * k, "image", dtype=object),
                       np.tile(np.array(["x", "y"], dtype=object), k),
                       np.full(2 * k, block.photos.ids[b], dtype=object), np.repeat(pid, 2),
                       np.repeat(np.arange(k), 2))
    func, start = transformation(xy_a, kind)
    what = f"pair {block.photos.ids[a]}-{block.photos.ids[b]}"
    if kind == "projective":  # start from the affine solution
        aff = design(xy_a, "affine")
        sol = np.linalg.lstsq(aff, xy_b.ravel(), rcond=None)[0]
        start = np.concatenate([sol, [0.0, 0.0]])

    try:
        first = SmallProblem(func, start, obs, what).fit(np.ones(2 * k, bool))
    except GeometryError:
        return None
    q = analyse(first, tests)
    stat = q.w if statistic == "w" else q.tau
    crit = q.k_w if statistic == "w" else q.k_tau
    tested = np.any(q.controlled.reshape(k, 2), axis=1)
    value = np.nanmax(np.abs(np.where(q.controlled, stat, np.nan)).reshape(k, 2), axis=1,
                      initial=0.0)
    try:
        run = iterative_snooping(first, tests, statistic=statistic, by_group=True)
        qf = run.quality
        v = run.model.residuals.reshape(k, 2)
        rejected = (~run.active).reshape(k, 2).any(axis=1)
        size = np.where(rejected, np.hypot(*v.T), 0.0)
        # the part of the error the point would show in the fit (r times the predicted
        # residual): at a point of low redundancy the extrapolated model errors show as well
        shown = np.hypot(*(v * qf.redundancy_number.reshape(k, 2)).T)
        # not more than the pair's own scatter (after the rejections) either
        own = qf.k_w * qf.sigma0_hat * float(sig[0]) if np.isfinite(qf.sigma0_hat) else 0.0
        tolerance_mm = max(tolerance_mm, own if statistic == "w" else 0.0)
        rejected &= shown > tolerance_mm
        final = np.abs(np.nan_to_num(qf.w if statistic == "w" else qf.tau)).reshape(k, 2)
        value = np.where(rejected, final.max(axis=1), value)
    except GeometryError:  # too many points rejected to fit the transformation
        run, rejected, size = None, np.zeros(k, bool), np.zeros(k)
        tested[:] = False
    return PairTest(a, b, kind, pts, tested, rejected, value, size, float(crit),
                    float(tolerance_mm), float(q.sigma0_hat), int(q.redundancy), run)


def _tol(block: Block, a: int, b: int, given: float | None, floor: float) -> float:
    return given if given is not None else max(relief_tolerance(block, a, b), floor)


def relief_tolerance(block: Block, a: int, b: int) -> float:
    """Parallax (mm) that the relief of the control heights causes between photos a, b.

    dp = c B dZ / H^2: B the base between the photos, H the flying height above the mean
    control height, dZ the range of the control heights (0 without three control heights).
    A 2D transformation cannot follow it; errors below it are left to stage 2.
    """
    z = block.points.xyz[block.points.controlled[:, 2], 2]
    eo = block.photos.eo
    if len(z) < 3:
        return 0.0
    h = float(np.median(eo[[a, b], 2]) - np.mean(z))
    if h <= 0:
        return 0.0
    c = float(block.cameras.focal_mm[block.photos.camera[a]])
    base = float(np.linalg.norm(eo[a, :2] - eo[b, :2]))
    return c * base * float(np.ptp(z)) / h**2


def blame(tests: list[PairTest]) -> dict[int, tuple[list[int], list[PairTest]]]:
    """For every rejected point: the photos to remove it from and the rejecting pairs.

    A photo is singled out when at least two tested pairs contain it (for this point), all of
    them reject the point, and it belongs to every rejecting pair; otherwise the point is
    removed from all photos of the rejecting pairs (one rejecting pair cannot tell which of
    its two photos is in error).
    """
    per_point: dict[int, list[tuple[PairTest, bool]]] = {}
    for t in tests:
        for j, p in enumerate(t.points):
            if t.tested[j]:
                per_point.setdefault(int(p), []).append((t, bool(t.rejected[j])))
    out = {}
    for p, entries in per_point.items():
        bad = [t for t, r in entries if r]
        if not bad:
            continue
        photos = {x for t, _ in entries for x in (t.a, t.b)}
        cand = []
        for ph in photos:
            mine = [r for t, r in entries if ph in (t.a, t.b)]
            if len(mine) >= 2 and all(mine) and all(ph in (t.a, t.b) for t in bad):
                cand.append(ph)
        remove = cand if len(cand) == 1 else sorted({x for t in bad for x in (t.a, t.b)})
        out[p] = (remove, bad)
    return out


def screen_pairs(block: Block, keep: np.ndarray, log: ScreeningLog, *, kind: str = "auto",
                 statistic: str = "w", tests: TestOptions = PAIR_TESTS,
                 min_redundancy: int = 4, tolerance_mm: float | None = None
                 ) -> tuple[np.ndarray, list[PairTest]]:
    """Stage 1 on the image rows where `keep` is True; returns the new keep and the tests.

    statistic "w": every pair is first snooped with its own variance factor (tau); the median
    of their final standard deviations is the a-priori sigma of a second, w-test snooping of
    every pair (a w-test is not bounded like tau, so several gross errors in one pair do not
    hide each other).  "tau": the first snooping only.
    tolerance_mm: errors smaller than this are not removed (None: the larger of the relief
    parallax of the pair, relief_tolerance, and the critical w times the pooled sigma).
    """
    keep = np.asarray(keep, bool).copy()
    ids = block.photos.ids
    pairs = []
    for a, b, ra, rb in common_points(block, keep, 2):
        use = choose_kind(len(ra), kind, min_redundancy)
        if use is not None:
            pairs.append((a, b, ra, rb, use))
    fits = [fit_pair(block, a, b, ra, rb, use, tests=tests, statistic="tau",
                     tolerance_mm=np.inf if statistic == "w" else _tol(block, a, b,
                                                                        tolerance_mm, 0.0))
            for a, b, ra, rb, use in pairs]
    final = [t.run.quality.sigma0_hat * t.run.model.sigma[0] for t in fits
             if t is not None and t.run is not None and np.isfinite(t.run.quality.sigma0_hat)]
    if statistic == "w" and final:
        pooled = float(np.median(final))
        k_w = b_method(tests.alpha0, tests.beta0).k_w
        log.note(1, "pairs", f"pooled sigma of the 2D transformations {pooled * 1e3:.0f} µm")
        fits = [fit_pair(block, a, b, ra, rb, use, tests=tests, statistic="w",
                         sigma_mm=pooled,
                         tolerance_mm=_tol(block, a, b, tolerance_mm, k_w * pooled))
                for a, b, ra, rb, use in pairs]
    failed = [f"{ids[a]}-{ids[b]}" for t, (a, b, *_) in zip(fits, pairs, strict=True)
              if t is None]
    if failed:
        log.note(1, "pairs", f"not fitted (not tested): {', '.join(failed)}")
    fits = [t for t in fits if t is not None]
    im = block.image
    ids = block.photos.ids
    for p, (photos, bad) in sorted(blame(fits).items()):
        pairs = ", ".join(f"{ids[t.a]}-{ids[t.b]} ({t.kind})" for t in bad)
        worst = max(bad, key=lambda t: t.value[np.flatnonzero(t.points == p)[0]])
        value = float(worst.value[np.flatnonzero(worst.points == p)[0]])
        single = len(photos) == 1
        size = max(float(t.size[np.flatnonzero(t.points == p)[0]]) for t in bad)
        if not single and size <= GROSS * max(t.tolerance for t in bad):
            log.add(Entry(1, f"pairs {pairs}", "image", block.points.ids[p],
                          ",".join(ids[ph] for ph in photos), action="kept",
                          statistic=statistic, value=value, critical=worst.critical,
                          reason=f"inconsistent in pair(s) {pairs} (error about {size:.2f} mm), "
                                 "but the photo in error cannot be singled out and the error is "
                                 "not gross: left to the strip formation"))
            continue
        reason = (f"inconsistent in pair(s) {pairs} (error about {size:.2f} mm)" +
                  ("" if single else "; the photo in error cannot be singled out"))
        for ph in photos:
            rows = np.flatnonzero(keep & (im.photo == ph) & (im.point == p))
            if not len(rows):
                continue
            keep[rows] = False
            log.add(Entry(1, f"pairs {pairs}", "image", block.points.ids[p], ids[ph],
                          statistic=statistic, value=value, critical=worst.critical,
                          reason=reason))
    log.note(1, "pairs", f"{len(fits)} photo pair(s) tested")
    return keep, fits
