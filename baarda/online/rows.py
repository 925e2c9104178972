"""Observation rows of the on-line bundle as the low-rank update takes them (online/lowrank.py).

New image points and GNSS/IMU observations are evaluated with the bundle's own code (the
camera models of bundle/image_rows.py; bundle/gnss_imu.py through online/kind_gnss_imu.py,
the rows of that kind) at the factorisation's estimate;
the rows of the factorisation's own observations come from its linearisation.  Each image
point gives two rows (x, y), each control point or GNSS position three (X, Y, Z; only the
observed coordinates of control), each IMU attitude three.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from baarda.adjustment.schur import SchurFactor
from baarda.block.photo_block import (
    Block,
    GroundPoints,
    ImagePoints,
)
from baarda.block.rotation import rotation_and_derivatives
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.image_rows import ImageRows
from baarda.kinds import CONTROL, IMAGE
from baarda.online.kind_gnss_imu import gnss_imu_rows, one_photo_each
from baarda.online.lowrank import KY, Rows, empty_rows
from baarda.online.measurements import Measurements


def take(rows: Rows, idx: np.ndarray) -> Rows:
    """The rows idx of rows."""
    return Rows(*(getattr(rows, f.name)[idx] for f in fields(Rows)))


def concat(parts: list[Rows], ng: int) -> Rows:
    parts = [p for p in parts if len(p)]
    if not parts:
        return empty_rows(ng)
    return Rows(*(np.concatenate([getattr(p, f) for p in parts])
                  for f in Rows.__dataclass_fields__))


def image_rows(block: Block, problem: BundleProblem, camera: np.ndarray, eo: np.ndarray,
               xyz: np.ndarray, xy: np.ndarray, g: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Misclosures e (k, 2) = observed - predicted and Jacobians je (k, 2, 6), jp (k, 2, 3),
    jg (k, 2, ng) of k image points: camera (k,), the photo's orientation eo (k, 6), the
    point xyz (k, 3), observed xy (k, 2) mm; g the global unknowns of `problem`."""
    k = len(camera)
    ng = problem.system.ng
    if not k:
        return np.zeros((0, 2)), np.zeros((0, 2, 6)), np.zeros((0, 2, 3)), np.zeros((0, 2, ng))
    tmp = Block(block.settings, block.cameras, one_photo_each(camera, eo),
                ImagePoints(np.arange(k), np.arange(k), np.asarray(xy, float), np.ones(k)),
                GroundPoints([str(i) for i in range(k)], np.asarray(xyz, float),
                             np.full((k, 3), np.nan), np.full(k, "tie", dtype=object)))
    cal = problem.calibration
    rows = ImageRows(tmp, cal, np.arange(k))
    eo = np.asarray(eo, float)
    rot = rotation_and_derivatives(eo[:, 3], eo[:, 4], eo[:, 5])
    f, je, jp, jpar = rows.evaluate(eo, np.asarray(xyz, float), cal.current(g), rot)
    jg = np.zeros((k, 2, ng))
    if cal.n:
        free = rows.free_columns(jpar)
        for i, cols in enumerate(cal.columns):
            sel = np.flatnonzero(np.asarray(camera) == i)
            if len(sel) and len(cols):
                jg[sel[:, None, None], np.arange(2)[None, :, None], cols[None, None, :]] = \
                    free[sel][:, :, :len(cols)]
    return np.asarray(xy, float) - f, je, jp, jg


def factor_rows(problem: BundleProblem, factor: SchurFactor, flat: np.ndarray) -> Rows:
    """The Jacobian rows of components `flat` of the factorisation's own observation
    vector (BundleProblem.layout order), as its linearisation has them (ycol -1, e 0)."""
    lay, s, lin = problem.layout, factor.system, factor.lin
    flat = np.asarray(flat, np.int64)
    k = len(flat)
    ng = s.ng
    frame = np.full(k, -1, np.int64)
    point = np.full(k, -1, np.int64)
    jf, jp, jg = np.zeros((k, 6)), np.zeros((k, 3)), np.zeros((k, ng))
    nm, nc = lay.m * lay.k, len(lay.ctrl_sel)
    img = flat < nm
    i, c = np.divmod(flat[img], lay.k)
    frame[img], point[img] = s.frame[i], s.point[i]
    jf[img], jp[img] = lin.jf[i, c], lin.jp[i, c]
    if ng and lin.jg is not None and s.gcol.shape[1]:
        sub = np.zeros((len(i), ng))
        for a in range(s.gcol.shape[1]):
            col = s.gcol[i, a]
            ok = col >= 0
            sub[np.flatnonzero(ok), col[ok]] += lin.jg[i[ok], c[ok], a]
        jg[img] = sub
    ctl = (flat >= nm) & (flat < nm + nc)
    ci, cc = np.divmod(lay.ctrl_sel[flat[ctl] - nm], lay.kc)
    point[ctl] = s.control_point[ci]
    jp[ctl] = lin.jc[ci, cc]
    ext = flat >= nm + nc
    x = flat[ext] - nm - nc
    if len(x):
        xr, xc = np.divmod(x, lay.kx)
        frame[ext] = s.x_frame[xr]
        assert lin.jxf is not None
        jf[ext] = lin.jxf[xr, xc]
        if ng:
            assert lin.jxg is not None
            jg[ext] = lin.jxg[xr, xc]
    none = np.full((k, KY), -1, np.int64)
    return Rows(frame, jf, point, jp, jg, none, np.zeros((k, KY)), np.zeros(k), np.zeros(k))


def group_rows(f, m: Measurements, cols: dict, group: dict, y0: np.ndarray
               ) -> tuple[list[tuple[str, int, int]], Rows]:
    """The observation rows of a group of held observations (online/entering.py) linearised
    at the estimate of the factorisation `f` (online/factorised.py `Factored`), new photos and
    points at y0 (their columns in `cols`): (their keys (kind, universe index, component),
    the Rows)."""
    res = f.result
    ng = f.problem.system.ng
    g = res.state[2] if len(res.state) == 3 else np.zeros(0)

    def photo_at(i):
        c = cols.get(("photo", i))
        return (y0[c:c + 6], c) if c is not None else (res.state[0][f.frame_of[i]], -1)

    def point_at(j):
        c = cols.get(("point", j))
        return (y0[c:c + 3], c) if c is not None else (res.state[1][f.elim_of[j]], -1)

    keys, parts = [], []
    img = group[IMAGE.name]
    if img:
        ph = [photo_at(m.im_photo[r]) for r in img]
        pt = [point_at(m.im_point[r]) for r in img]
        e, je, jp, jg = image_rows(f.problem.block, f.problem,
                                   np.array([m.photo_cam[m.im_photo[r]] for r in img]),
                                   np.array([p[0] for p in ph]), np.array([p[0] for p in pt]),
                                   np.array([m.im_xy[r] for r in img]), g)
        k = 2 * len(img)
        frame = np.repeat([f.frame_of[m.im_photo[r]] if c < 0 else -1
                           for r, (_, c) in zip(img, ph, strict=True)], 2)
        point = np.repeat([f.elim_of[m.im_point[r]] if c < 0 else -1
                           for r, (_, c) in zip(img, pt, strict=True)], 2)
        pc = np.repeat([c for _, c in ph], 2)
        qc = np.repeat([c for _, c in pt], 2)
        je, jp = je.reshape(k, 6), jp.reshape(k, 3)
        held = f.problem.held
        if held is not None:  # a free network's datum: its columns are not unknowns
            je = np.where(held[np.maximum(frame, 0)] & (frame >= 0)[:, None], 0.0, je)
        ycol = np.full((k, KY), -1, np.int64)
        jy = np.zeros((k, KY))
        on = pc >= 0
        ycol[on, :6] = pc[on, None] + np.arange(6)
        jy[on, :6] = je[on]
        on = qc >= 0
        ycol[on, 6:] = qc[on, None] + np.arange(3)
        jy[on, 6:] = jp[on]
        sig = np.array([m.im_sigma[r] for r in img]).reshape(k)
        parts.append(Rows(frame, np.where((frame >= 0)[:, None], je, 0.0), point,
                          np.where((point >= 0)[:, None], jp, 0.0), jg.reshape(k, ng),
                          ycol, jy, sig, e.reshape(k)))
        keys += [(IMAGE.name, r, c) for r in img for c in range(2)]
    for j in group[CONTROL.name]:
        sig = m.point_sigma[j]
        obs = np.flatnonzero(np.isfinite(sig))
        x, c = point_at(j)
        k = len(obs)
        jp = np.eye(3)[obs]
        ycol = np.full((k, KY), -1, np.int64)
        jy = np.zeros((k, KY))
        if c >= 0:
            ycol[:, 6:] = c + np.arange(3)
            jy[:, 6:] = jp
        parts.append(Rows(np.full(k, -1), np.zeros((k, 6)),
                          np.full(k, f.elim_of[j] if c < 0 else -1),
                          jp if c < 0 else np.zeros((k, 3)), np.zeros((k, ng)), ycol, jy,
                          sig[obs], (m.point_xyz[j] - x)[obs]))
        keys += [(CONTROL.name, j, int(a)) for a in obs]
    ext_keys, ext_rows = gnss_imu_rows(f, m, group, photo_at)
    keys += ext_keys
    parts.append(ext_rows)
    return keys, concat(parts, ng)
