"""Stage 2: progressive strip formation with data snooping after every photo.

The first photo of a strip keeps its approximate orientation; the second is relatively
oriented to it by the collinearity equations (one base component fixed: the scale), with
simultaneous intersection of the model points.  Every further photo is oriented to the strip
formed so far: its unknowns are its six orientation elements and the points of the new model;
points already in the strip enter with their strip coordinates as weighted observations
(positional constraint, variances from the step that formed them), which carries the scale
into the new model.  New points are intersected from their rays on all photos of the strip.

After every photo the step is snooped (baarda.quality.iterative, whole image points and whole
constraints as groups, w-test with the a-priori sigmas).  A rejection is accepted when its
test can be separated from the tests of the other observations of the same point
(|rho| < rho_max, quality.statistics.w_correlation); otherwise the point is suspended (and the
strip position of an old point that disagrees with the new photo likewise): it is formed again
when the next photo adds a ray.  At the end a strip adjustment (every photo free but the
datum: the first photo and one base component) takes all rays of the strip and settles the
suspended points: a separable rejection is removed; what still cannot be separated is left to
the bundle adjustment, where more observations may locate it (FOTEF: remove in the
pre-adjustment what shows up clearly, leave the rest to data snooping).  The strip coordinates
and their cofactors for stage 3 come from the strip adjustment.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import cast

import numpy as np

from baarda.block.photo_block import Block
from baarda.errors import GeometryError
from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.iterative import SnoopingRun, iterative_snooping
from baarda.quality.iterative import label as obs_label
from baarda.quality.statistics import w_correlation
from baarda.screening.fit import SmallModel, largest_test, separable
from baarda.screening.intersection import Intersection
from baarda.screening.log import Entry, ScreeningLog


@dataclass
class Strip:
    """A strip formed in its own frame (the first photo's approximate orientation)."""

    label: str
    photos: list[int]  # flight order
    eo: np.ndarray  # (n_photos of the block, 6): NaN where not oriented
    xyz: dict[int, np.ndarray] = field(default_factory=dict)  # point -> strip coordinates
    var: dict[int, np.ndarray] = field(default_factory=dict)  # their variances (sigma0 = 1)
    qxx: np.ndarray | None = None  # cofactors of the strip adjustment's unknowns
    qrows: dict[int, np.ndarray] = field(default_factory=dict)  # point -> its 3 rows in qxx

    def covariance(self, points: list[int]) -> np.ndarray:
        """(3n, 3n) cofactor matrix of the strip coordinates of `points` (strip datum)."""
        if self.qxx is not None and all(p in self.qrows for p in points):
            idx = np.concatenate([self.qrows[p] for p in points])
            return self.qxx[np.ix_(idx, idx)]
        return np.diag(np.concatenate([self.var[p] for p in points]))
    notes: list[str] = field(default_factory=list)

    @property
    def oriented(self) -> list[int]:
        return [p for p in self.photos if np.all(np.isfinite(self.eo[p]))]


def strip_photos(block: Block) -> list[tuple[str, list[int]]]:
    """Photos of every labelled strip in flight order (along the strip's main direction)."""
    out = []
    labels = block.photos.strip
    for lab in dict.fromkeys(str(s) for s in labels):
        if not lab.strip():
            continue
        idx = np.flatnonzero(labels.astype(str) == lab)
        xy = block.photos.eo[idx, :2]
        if len(idx) > 1:
            d = np.linalg.svd(xy - xy.mean(axis=0))[2][0]
            t = (xy - xy.mean(axis=0)) @ d
            order = np.argsort(t, kind="stable")
            if order[0] != 0 and order[-1] == 0:  # keep the direction of the file
                order = order[::-1]
            idx = idx[order]
        out.append((lab, [int(i) for i in idx]))
    return out


@dataclass
class Decision:
    group: int
    point: int
    component: int  # largest |w| of the group
    w: float
    critical: float
    separable: bool
    rho: float
    other: str  # label of the least separable other observation


def _examine(prob: Intersection, run: SnoopingRun, tests: TestOptions,
             rho_max: float) -> list[Decision]:
    """Separability of every group that the snooping rejected."""
    out = []
    obs = prob.obs
    for g in np.unique(obs.group[~run.active]):
        comps = np.flatnonzero(obs.group == g)
        act = run.active.copy()
        act[comps] = True
        model = cast(SmallModel, run.model.refit(act))
        test = comps[model.active[comps]]
        point = int(prob.points[prob.comp_point[comps[0]]])
        if len(test) == 0:
            continue
        i, w, crit = largest_test(model, test, tests)
        others = prob.components(point)
        others = others[model.active[others] & ~np.isin(others, comps)]
        ok, rho = separable(model, i, others, rho_max)
        other = ""
        if len(others):
            j = others[int(np.argmax(np.abs(w_correlation(model, i)[others])))]
            other = obs_label(model, int(j))
        out.append(Decision(int(g), point, int(i), w, crit, ok, rho, other))
    return out


def _step(block: Block, strip: Strip, k: int, keep: np.ndarray, log: ScreeningLog,
          suspended: set[int], tests: TestOptions, rho_max: float) -> bool:
    """Orient photo k of the strip; returns False when it cannot be oriented."""
    im = block.image
    photos = strip.photos
    pk, prev, earlier = photos[k], photos[k - 1], photos[:k]
    approx = block.photos.eo
    start = strip.eo[prev] + (approx[pk] - approx[prev])
    fixed = _base_component(block, photos) if k == 1 else None  # the scale
    ctx = f"strip {strip.label}, photo {block.photos.ids[pk]}"
    rows_k = np.flatnonzero(keep & (im.photo == pk))
    pts = np.unique(im.point[rows_k])
    old = [int(p) for p in pts if int(p) in strip.xyz]
    on_earlier = keep & np.isin(im.photo, earlier)
    new = [int(p) for p in pts if int(p) not in strip.xyz
           and np.any(on_earlier & (im.point == p))]
    if len(old) + len(new) < 3:
        strip.notes.append(f"{ctx}: {len(old) + len(new)} point(s) in common with the "
                           "strip: not oriented; strip formation stops here")
        return False
    rows = np.concatenate([rows_k[np.isin(im.point[rows_k], old + new)],
                           np.flatnonzero(on_earlier & np.isin(im.point, new))])
    eo = strip.eo.copy()
    eo[pk] = start
    prob = Intersection(block, eo, rows, [pk], {p: (strip.xyz[p], strip.var[p]) for p in old},
                        None if fixed is None else {pk: [fixed]}, what=ctx)
    try:
        run = iterative_snooping(prob.fit(np.ones(prob.obs.n, bool)), tests, by_group=True)
    except GeometryError as e:
        strip.notes.append(f"{ctx}: not oriented ({e}); strip formation stops here")
        return False
    decisions = _examine(prob, run, tests, rho_max)
    ids = block.points.ids
    suspect: set[int] = set()
    for d in decisions:
        comps = np.flatnonzero(prob.obs.group == d.group)
        if d.separable and prob.obs.kind[comps[0]] == "image":
            row = prob.rows[d.group]
            keep[row] = False
            log.add(Entry(2, ctx, "image", ids[d.point], block.photos.ids[im.photo[row]],
                          statistic="w", value=d.w, critical=d.critical,
                          reason=f"rejected in the step (|rho| = {d.rho:.2f} with the other "
                                 "observations of the point)"))
            continue
        # not located (or the strip position of an old point disagrees with the new ray):
        # the point is formed again with all its rays when the next photo or the end comes
        suspect.add(d.point)
        rays = np.flatnonzero(keep & np.isin(im.photo, photos[:k + 1]) & (im.point == d.point))
        what = (f"not separable from {d.other} (|rho| = {d.rho:.2f})" if not d.separable else
                "its strip position from the earlier photos disagrees with this photo")
        log.add(Entry(2, ctx, "image", ids[d.point],
                      ",".join(block.photos.ids[im.photo[r]] for r in rays), action="suspended",
                      statistic="w", value=d.w, critical=d.critical,
                      reason=f"rejected, but {what}: formed again with all its rays later"))
    model = cast(SmallModel, run.model)
    eo_all, xyz = model.x
    strip.eo[pk] = eo_all[pk]
    qxx = np.diag(model.qxx)
    for r, lab in zip(model.point_rows if model.point_rows is not None else [],
                      model.point_labels or [], strict=True):
        p = block.point_index[lab]
        if p in suspect:
            continue
        strip.xyz[p] = xyz[prob.pindex[p]]
        strip.var[p] = qxx[r]
        suspended.discard(p)
    for p in suspect:
        strip.xyz.pop(p, None)
        strip.var.pop(p, None)
        suspended.add(p)
    return True


MAX_DENSE_UNKNOWNS = 3000  # strip adjustments beyond this size are skipped (dense solver)


def _base_component(block: Block, photos: list[int]) -> int:
    """The base component along the flight between the first two photos: held (the scale)."""
    approx = block.photos.eo
    return int(np.argmax(np.abs(approx[photos[1], :2] - approx[photos[0], :2])))


def _strip_adjustment(block: Block, strip: Strip, keep: np.ndarray, log: ScreeningLog,
                      suspended: set[int], tests: TestOptions, rho_max: float) -> None:
    """All rays of the strip with every photo free but the datum, snooped like a step.

    It settles the points suspended in the steps: a separable rejection of a suspended point is
    removed; anything else it rejects is left to the bundle adjustment (logged as kept).
    """
    im = block.image
    photos = strip.oriented
    ctx = f"strip {strip.label}, strip adjustment"
    if len(photos) < 2:
        return
    rows = np.flatnonzero(keep & np.isin(im.photo, photos))
    rays = np.bincount(im.point[rows], minlength=len(block.points))
    rows = rows[rays[im.point[rows]] >= 2]
    u = 6 * (len(photos) - 1) - 1 + 3 * len(np.unique(im.point[rows]))
    if u > MAX_DENSE_UNKNOWNS:
        strip.notes.append(f"{ctx}: {u} unknowns, too many for the dense strip adjustment: "
                           "skipped (suspended points are left to the bundle adjustment)")
        return
    prob = Intersection(block, strip.eo, rows, photos[1:], None,
                        {photos[1]: [_base_component(block, photos)]}, what=ctx)
    try:
        run = iterative_snooping(prob.fit(np.ones(prob.obs.n, bool)), tests, by_group=True)
    except GeometryError as e:
        strip.notes.append(f"{ctx}: failed ({e}); the strip is kept as formed")
        return
    decisions = _examine(prob, run, tests, rho_max)
    ids = block.points.ids
    for d in decisions:
        row = prob.rows[d.group]
        if d.separable and d.point in suspended:
            keep[row] = False
            log.add(Entry(2, ctx, "image", ids[d.point], block.photos.ids[im.photo[row]],
                          statistic="w", value=d.w, critical=d.critical,
                          reason=f"rejected in the strip adjustment (|rho| = {d.rho:.2f} with "
                                 "the other observations of the point)"))
        else:
            rays_p = prob.rows[np.unique(prob.obs.group[prob.components(d.point)])]
            why = (f"not separable from {d.other} (|rho| = {d.rho:.2f})" if not d.separable
                   else "not suspected in the steps (an effect of another error?)")
            log.add(Entry(2, ctx, "image", ids[d.point],
                          ",".join(block.photos.ids[im.photo[r]] for r in rays_p),
                          action="kept", statistic="w", value=d.w, critical=d.critical,
                          reason=f"rejected on photo {block.photos.ids[im.photo[row]]}, but "
                                 f"{why}: left to the bundle adjustment"))
    model = cast(SmallModel, run.model)
    eo, xyz = model.x
    strip.eo[photos] = eo[photos]
    qxx = np.diag(model.qxx)
    strip.xyz.clear()
    strip.var.clear()
    strip.qxx = model.qxx
    for r, lab in zip(model.point_rows if model.point_rows is not None else [],
                      model.point_labels or [], strict=True):
        p = block.point_index[lab]
        strip.xyz[p] = xyz[prob.pindex[p]]
        strip.var[p] = qxx[r]
        strip.qrows[p] = np.asarray(r)
    suspended.clear()


def form_strip(block: Block, label: str, photos: list[int], keep: np.ndarray,
               log: ScreeningLog, *, tests: TestOptions = DEFAULT_TESTS,
               rho_max: float = 0.9) -> Strip:
    """Form one strip; updates `keep` (image rows) in place and logs every decision."""
    eo = np.full((len(block.photos), 6), np.nan)
    eo[photos[0]] = block.photos.eo[photos[0]]
    strip = Strip(label, list(photos), eo)
    suspended: set[int] = set()
    for k in range(1, len(photos)):
        if not _step(block, strip, k, keep, log, suspended, tests, rho_max):
            break
    _strip_adjustment(block, strip, keep, log, suspended, tests, rho_max)
    for n in strip.notes:
        log.note(2, f"strip {label}", n)
    return strip


def screen_strips(block: Block, keep: np.ndarray, log: ScreeningLog, *,
                  tests: TestOptions = DEFAULT_TESTS,
                  rho_max: float = 0.9) -> tuple[np.ndarray, list[Strip]]:
    """Stage 2 for every labelled strip; returns the new keep mask and the strips."""
    keep = np.asarray(keep, bool).copy()
    strips = []
    groups = strip_photos(block)
    if not groups:
        log.note(2, "strips", "no strip labels in photos.csv: strip formation skipped")
    for label, photos in groups:
        if len(photos) < 2:
            log.note(2, f"strip {label}", "one photo only: not formed")
            continue
        strips.append(form_strip(block, label, photos, keep, log, tests=tests,
                                 rho_max=rho_max))
    return keep, strips
