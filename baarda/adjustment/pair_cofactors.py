"""Off-diagonal cofactors of the adjusted observations, (A N^-1 A^T)_ij, for the pairs of
rows that share an eliminated point or a frame, from one SchurFactor.

With M = Hpp (block-diagonal: the points), Sigma the frames' block of N0^-1 (globals held),
G_p = M_p^-1 H_pF and the global unknowns eliminated last (C, Y: adjustment/schur.py):

    (A N^-1 A^T)_ij = d_ij jp_i M^-1 jp_j^T + (RA)_i Sigma (RA)_j^T + b_i C^-1 b_j^T,
    (RA)_i = jf_i e_f(i) - jp_i G_p(i),  b = A0 Y - Ag,

d_ij = 1 when i and j observe the same point.  Pairs of one point need the frames of that
point only, which share it and so lie on the pattern of L; pairs of one frame with different
points need Sigma between every two frames that see one of its points (at most two photos
apart through it), which L may lack: those come from the selected inverse on a larger
pattern (linalg/extended.py).  `local_diag` is the first term's diagonal; q_ll,ii minus it
is the part that the frames (and globals) carry, the bound of every cross-point pair by
Cauchy-Schwarz (quality/separability.py).

Rows are flat (adjustment/schur_model.FlatLayout); results come as triplets (i, j, q) with
i < j, in chunks.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

from baarda.linalg._jit import kernel
from baarda.linalg.extended import selected_inverse_including

if TYPE_CHECKING:
    from baarda.adjustment.schur import SchurFactor
    from baarda.adjustment.schur_model import FlatLayout

Triplets = tuple[np.ndarray, np.ndarray, np.ndarray]
CHUNK = 1_000_000  # observation pairs per chunk


def border_factor(factor: SchurFactor, layout: FlatLayout) -> np.ndarray:
    """E (n, ng) with E_i . E_j = b_i C^-1 b_j^T (zero columns without global unknowns)."""
    if not factor.system.ng:
        return np.zeros((layout.n, 0))
    parts = factor._border_rows()
    b = layout.flat(*parts) if layout.mx else layout.flat(parts[0], parts[1])
    lc = np.linalg.cholesky(factor._c_inv())
    return np.ascontiguousarray(b @ lc)


def local_diag(factor: SchurFactor, layout: FlatLayout) -> np.ndarray:
    """(n,) jp M^-1 jp^T of every row: the cofactor of the adjusted observation were the
    frames and the global unknowns known (zero for rows without an eliminated point)."""
    s, lin = factor.system, factor.lin
    hinv = factor.hpp_inv  # per point, the kernels' order is by point: hpp_inv is per point
    img = np.einsum("mkd,mde,mke->mk", lin.jp, hinv[s.point], lin.jp)
    ctl = np.einsum("mkd,mde,mke->mk", lin.jc, hinv[s.control_point], lin.jc)
    if layout.mx:
        return layout.flat(img, ctl, np.zeros((layout.mx, layout.kx)))
    return layout.flat(img, ctl)


def _control_flat(layout: FlatLayout) -> np.ndarray:
    """(n_control, kc) flat row of every point-observation row, -1 where not observed."""
    out = np.full(layout.n_control * layout.kc, -1, np.int64)
    out[layout.ctrl_sel] = layout.m * layout.k + np.arange(len(layout.ctrl_sel))
    return out.reshape(layout.n_control, layout.kc)


@kernel
def _point_pairs(pa, pc, slot, tr, order, frame, k, jf, jp, spf, spp, point, zff, e,
                 oi, oj, oq, n0):
    """Triplets of the image rows of pairs (pa, pc) of observations of one point (sorted
    positions; zff[slot] the frames' block of Sigma, transposed where tr).  Writes from n0;
    returns the next free position."""
    b = jf.shape[2]
    d = jp.shape[2]
    ng = e.shape[1]
    n = n0
    t1 = np.empty((k, b))
    t2 = np.empty((k, d))
    for q in range(pa.size):
        a = order[pa[q]]
        c = order[pc[q]]
        same = a == c
        if frame[a] == frame[c] and a > c:
            continue  # twin rays on one frame: each pair once
        z = zff[slot[q]]
        p = point[a]
        for r in range(k):
            # t1 = jf_a Z (Z = Sigma[f_a, f_c]) and t2 = jf_a Sigma_fp + jp_a Sigma_pp
            for y in range(b):
                acc = 0.0
                for x in range(b):
                    acc += jf[a, r, x] * (z[y, x] if tr[q] else z[x, y])
                t1[r, y] = acc
            for y in range(d):
                acc = 0.0
                for x in range(b):
                    acc += jf[a, r, x] * spf[a, y, x]
                for x in range(d):
                    acc += jp[a, r, x] * spp[p, x, y]
                t2[r, y] = acc
        for r in range(k):
            for s in range(k):
                if same and s <= r:
                    continue
                acc = 0.0
                for y in range(b):
                    acc += t1[r, y] * jf[c, s, y]
                for y in range(d):
                    acc += t2[r, y] * jp[c, s, y]
                # jp_a Sigma_pf_c jf_c^T
                for x in range(d):
                    u = 0.0
                    for y in range(b):
                        u += spf[c, x, y] * jf[c, s, y]
                    acc += jp[a, r, x] * u
                i = a * k + r
                j = c * k + s
                for g in range(ng):
                    acc += e[i, g] * e[j, g]
                oi[n] = min(i, j)
                oj[n] = max(i, j)
                oq[n] = acc
                n += 1
    return n


@kernel
def _control_pairs(cpt, cflat, jc, ptr, order, k, jf, jp, spf, spp, e, oi, oj, oq):
    """Triplets of each point observation's rows with each other and with the image rows of
    its point.  Returns the number written."""
    b = jf.shape[2]
    d = jp.shape[2]
    ng = e.shape[1]
    kc = jc.shape[1]
    n = 0
    for c in range(cpt.size):
        p = cpt[c]
        for r in range(kc):
            i = cflat[c, r]
            if i < 0:
                continue
            for s in range(r + 1, kc):
                j = cflat[c, s]
                if j < 0:
                    continue
                acc = 0.0
                for x in range(d):
                    for y in range(d):
                        acc += jc[c, r, x] * spp[p, x, y] * jc[c, s, y]
                for g in range(ng):
                    acc += e[i, g] * e[j, g]
                oi[n] = i
                oj[n] = j
                oq[n] = acc
                n += 1
            for t in range(ptr[p], ptr[p + 1]):
                o = order[t]
                for s in range(k):
                    acc = 0.0
                    for x in range(d):
                        u = 0.0
                        for y in range(b):
                            u += spf[o, x, y] * jf[o, s, y]
                        for y in range(d):
                            u += spp[p, x, y] * jp[o, s, y]
                        acc += jc[c, r, x] * u
                    j = o * k + s
                    for g in range(ng):
                        acc += e[i, g] * e[j, g]
                    oi[n] = min(i, j)
                    oj[n] = max(i, j)
                    oq[n] = acc
                    n += 1
    return n


def point_pairs(factor: SchurFactor, layout: FlatLayout) -> Iterator[Triplets]:
    """(i, j, q_ij) of every two rows of one eliminated point (image rows on its frames and
    its point-observation rows), i < j, in chunks."""
    s, lin = factor.system, factor.lin
    sel, _, spf, spp = factor.covariances()
    zff = sel.pattern_values()
    e = border_factor(factor, layout)
    k = layout.k
    args = (s.order, s.frame, k, lin.jf, lin.jp, spf, spp, s.point, zff, e)
    for lo in range(0, len(s.pair_a), CHUNK):
        hi = min(lo + CHUNK, len(s.pair_a))
        size = (hi - lo) * k * k
        oi, oj = np.empty(size, np.int64), np.empty(size, np.int64)
        oq = np.empty(size)
        n = _point_pairs(s.pair_a[lo:hi], s.pair_c[lo:hi], s.pair_slot[lo:hi],
                         s.pair_tr[lo:hi], *args, oi, oj, oq, 0)
        yield oi[:n], oj[:n], oq[:n]
    if layout.n_control:
        cflat = _control_flat(layout)
        rays = np.diff(s.ptr)[s.control_point]
        size = int(np.sum(layout.kc * (layout.kc + k * rays)))
        oi, oj = np.empty(size, np.int64), np.empty(size, np.int64)
        oq = np.empty(size)
        n = _control_pairs(s.control_point, cflat, lin.jc, s.ptr, s.order, k, lin.jf, lin.jp,
                           spf, spp, e, oi, oj, oq)
        yield oi[:n], oj[:n], oq[:n]


def _frame_rows(factor: SchurFactor, layout: FlatLayout, frames: np.ndarray):
    """For each frame in `frames`: its observations (original indices) and extra rows."""
    s = factor.system
    by_frame = np.argsort(s.frame, kind="stable")
    fptr = np.searchsorted(s.frame[by_frame], np.arange(s.nf + 1))
    xf = s.x_frame
    x_by = np.argsort(xf, kind="stable")
    xptr = np.searchsorted(xf[x_by], np.arange(-1, s.nf + 1))[1:]  # skip frame -1
    return [(by_frame[fptr[f]:fptr[f + 1]], x_by[xptr[f]:xptr[f + 1]]) for f in frames]


def frame_pairs(factor: SchurFactor, layout: FlatLayout,
                frames: np.ndarray) -> Iterator[Triplets]:
    """(i, j, q_ij) of every two rows on one of the system frames `frames` (image rows of
    its observations and extra rows tied to it), i < j, one frame at a time."""
    s, lin = factor.system, factor.lin
    frames = np.unique(np.asarray(frames, np.int64))
    if not len(frames):
        return
    k, b = layout.k, s.b
    e = border_factor(factor, layout)
    rows = _frame_rows(factor, layout, frames)
    # the frames that see the points of each frame, and the pairs of them that Sigma needs
    hoods, need_r, need_c = [], [], []
    for f, (obs, _) in zip(frames, rows, strict=True):
        pts = np.unique(s.point[obs])
        seen = np.concatenate([s.frame_sorted[s.ptr[p]:s.ptr[p + 1]] for p in pts] + [[f]])
        hood = np.unique(seen)
        hoods.append(hood)
        rr, cc = np.meshgrid(hood, hood, indexing="ij")
        low = rr > cc
        need_r.append(rr[low])
        need_c.append(cc[low])
    sel = selected_inverse_including(factor.chol, np.concatenate(need_r),
                                     np.concatenate(need_c))
    hinv = factor.hpp_inv
    base = layout.m * k + len(layout.ctrl_sel)  # the first extra row
    for f, (obs, xr), hood in zip(frames, rows, hoods, strict=True):
        nh = len(hood)
        col = {int(g): n for n, g in enumerate(hood)}
        nr = len(obs) * k + len(xr) * (layout.kx if layout.mx else 0)
        bm = np.zeros((nr, nh * b))
        flat = np.empty(nr, np.int64)
        for n, o in enumerate(obs):
            r0 = n * k
            flat[r0:r0 + k] = o * k + np.arange(k)
            c = col[int(f)]
            bm[r0:r0 + k, c * b:(c + 1) * b] += lin.jf[o]
            p = s.point[o]
            jpm = lin.jp[o] @ hinv[p]  # (k, d)
            for t in range(s.ptr[p], s.ptr[p + 1]):
                g = col[int(s.frame_sorted[t])]
                bm[r0:r0 + k, g * b:(g + 1) * b] -= jpm @ factor.hfp[t].T
        if len(xr):
            kx = layout.kx
            r1 = len(obs) * k
            c = col[int(f)]
            for n, x in enumerate(xr):
                flat[r1 + n * kx:r1 + (n + 1) * kx] = base + x * kx + np.arange(kx)
                bm[r1 + n * kx:r1 + (n + 1) * kx, c * b:(c + 1) * b] = lin.jxf[x]
        rr, cc = np.meshgrid(hood, hood, indexing="ij")
        sig = sel.blocks(rr.ravel(), cc.ravel()).reshape(nh, nh, b, b)
        sig = sig.transpose(0, 2, 1, 3).reshape(nh * b, nh * b)
        q = bm @ sig @ bm.T + e[flat] @ e[flat].T
        # the same point on this frame: the x and y of one image point (and twin rays)
        if len(obs):
            jp = lin.jp[obs]
            pts = s.point[obs]
            same = pts[:, None] == pts[None, :]
            loc = np.einsum("akd,ade,cle->akcl", jp, hinv[pts], jp)
            loc = loc * same[:, None, :, None]
            q[:len(obs) * k, :len(obs) * k] += loc.reshape(len(obs) * k, len(obs) * k)
        iu, ju = np.triu_indices(nr, 1)
        a, c = flat[iu], flat[ju]
        yield np.minimum(a, c), np.maximum(a, c), q[iu, ju]



def columns(factor: SchurFactor, layout: FlatLayout, rows: np.ndarray) -> np.ndarray:
    """Columns `rows` of A N^-1 A^T (n, q) from the rows' own Jacobians (rejected rows
    included: their weight is zero, their Jacobian is not)."""
    s, lin = factor.system, factor.lin
    rows = np.atleast_1d(np.asarray(rows, np.int64))
    q = len(rows)
    gf, gp = np.zeros((s.nf, s.b, q)), np.zeros((s.np, s.d, q))
    gg = np.zeros((s.ng, q))
    nm, ncs = layout.m * layout.k, len(layout.ctrl_sel)
    for c, i in enumerate(rows.tolist()):
        if i < nm:
            o, r = divmod(i, layout.k)
            gf[s.frame[o], :, c] += lin.jf[o, r]
            gp[s.point[o], :, c] += lin.jp[o, r]
            if lin.jg is not None and s.gcol.shape[1]:
                ok = s.gcol[o] >= 0
                np.add.at(gg[:, c], s.gcol[o][ok], lin.jg[o, r][ok])
        elif i < nm + ncs:
            cc, r = divmod(int(layout.ctrl_sel[i - nm]), layout.kc)
            gp[s.control_point[cc], :, c] += lin.jc[cc, r]
        else:
            x, r = divmod(i - nm - ncs, layout.kx)
            if s.x_frame[x] >= 0:
                gf[s.x_frame[x], :, c] += lin.jxf[x, r]
            gg[:, c] += lin.jxg[x, r]
    if factor.has_border:
        return layout.flat(*factor.apply_A(*factor.solve_normal(gf, gp, gg)))
    return layout.flat(*factor.apply_A(*factor.solve_normal(gf, gp)))
