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
from baarda.linalg.extended import block_lookup, read_block, selected_inverse_including

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


def _emit_pair(e, i, j, acc, oi, oj, oq, n):
    """Write triplet n: rows (i, j) in ascending order and their cofactor acc plus the
    border's term e_i . e_j (the rows' reduced global columns); returns n + 1."""
    for g in range(e.shape[1]):
        acc += e[i, g] * e[j, g]
    oi[n] = min(i, j)
    oj[n] = max(i, j)
    oq[n] = acc
    return n + 1


_emit = kernel(_emit_pair, inline="always")


@kernel
def _point_pairs(pa, pc, slot, tr, order, frame, k, jf, jp, spf, spp, point, zff, e,
                 oi, oj, oq, n0):
    """Triplets of the image rows of pairs (pa, pc) of observations of one point (sorted
    positions; zff[slot] the frames' block of Sigma, transposed where tr).  Writes from n0;
    returns the next free position."""
    b = jf.shape[2]
    d = jp.shape[2]
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
                n = _emit(e, a * k + r, c * k + s, acc, oi, oj, oq, n)
    return n


@kernel
def _control_pairs(cpt, cflat, jc, ptr, order, k, jf, jp, spf, spp, e, oi, oj, oq):
    """Triplets of each point observation's rows with each other and with the image rows of
    its point.  Returns the number written."""
    b = jf.shape[2]
    d = jp.shape[2]
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
                n = _emit(e, i, j, acc, oi, oj, oq, n)
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
                    n = _emit(e, i, o * k + s, acc, oi, oj, oq, n)
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


def _by_frame(keys: np.ndarray, nf: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR (ptr (nf + 1,), index) of the items of each frame (keys -1: none)."""
    order = np.argsort(keys, kind="stable")
    ptr = np.searchsorted(keys[order], np.arange(nf + 1))
    return ptr.astype(np.int64), order.astype(np.int64)


def _row_blocks_of(r, nobs, k, obs, point, ptr, frame_sorted, colof, blocks):
    """The distinct nonzero column blocks of row r of B into `blocks`, their count: the
    frames that see the point of an image row (a frame with two rays to it once), block 0
    (the frame's own) for an extra row."""
    if r >= nobs * k:
        blocks[0] = 0
        return 1
    p = point[obs[r // k]]
    n = 0
    for t in range(ptr[p], ptr[p + 1]):
        blk = colof[frame_sorted[t]]
        seen = False
        for u in range(n):
            seen = seen or blocks[u] == blk
        if not seen:
            blocks[n] = blk
            n += 1
    return n


_row_blocks = kernel(_row_blocks_of, inline="always")


@kernel
def _sandwich(bm, sig, nobs, k, b, obs, point, ptr, frame_sorted, colof):
    """(nr, nr) q with q[r, s] = (bm sig bm^T)[r, s] for r < s (the rest zero) over the
    nonzero column blocks of each row of bm only (_row_blocks; obs: the frame's
    observations, k rows each; colof: a frame's block).  In an aerial block a row has about
    5 of the 20-25 blocks: a fifth of the dense product's work, without a BLAS call per
    frame."""
    nr, nc = bm.shape
    blocks = np.empty(nc // b, np.int64)
    wm = np.zeros((nr, nc))  # bm sig
    for r in range(nr):
        for i in range(_row_blocks(r, nobs, k, obs, point, ptr, frame_sorted, colof, blocks)):
            for x in range(blocks[i] * b, blocks[i] * b + b):
                v = bm[r, x]
                if v != 0.0:
                    for y in range(nc):
                        wm[r, y] += v * sig[x, y]
    q = np.zeros((nr, nr))
    for s in range(1, nr):
        for i in range(_row_blocks(s, nobs, k, obs, point, ptr, frame_sorted, colof, blocks)):
            for r in range(s):
                acc = 0.0
                for x in range(blocks[i] * b, blocks[i] * b + b):
                    acc += wm[r, x] * bm[s, x]
                q[r, s] += acc
    return q


@kernel
def _frame_pairs(frames, fptr, fobs, xptr, xobs, ptr, frame_sorted, point, jf, jp, hinv,
                 hfp, jxf, e, k, kx, base, colptr, rowind, iperm, slot_pos, slot_stride,
                 panels, oi, oj, oq):
    """Triplets of every two rows on each frame of `frames`: B Sigma B^T over the frames
    that see its points, the point-local term of rows of one point, the border term.
    Returns the number written."""
    nf = fptr.size - 1
    b = jf.shape[2]
    d = jp.shape[2]
    mark = np.full(nf, -1, np.int64)
    colof = np.zeros(nf, np.int64)
    hood = np.zeros(nf, np.int64)
    blk = np.zeros((b, b))
    n = 0
    for fi in range(frames.size):
        f = frames[fi]
        o0, o1 = fptr[f], fptr[f + 1]
        x0, x1 = xptr[f], xptr[f + 1]
        nobs = o1 - o0
        nr = nobs * k + (x1 - x0) * kx
        if nr < 2:
            continue
        nh = 0
        mark[f] = fi
        colof[f] = 0
        hood[0] = f
        nh = 1
        for a in range(o0, o1):
            p = point[fobs[a]]
            for t in range(ptr[p], ptr[p + 1]):
                g = frame_sorted[t]
                if mark[g] != fi:
                    mark[g] = fi
                    colof[g] = nh
                    hood[nh] = g
                    nh += 1
        bm = np.zeros((nr, nh * b))
        flat = np.empty(nr, np.int64)
        tmp = np.empty((k, d))
        for a in range(nobs):
            o = fobs[o0 + a]
            p = point[o]
            for r in range(k):
                flat[a * k + r] = o * k + r
                for y in range(b):
                    bm[a * k + r, y] += jf[o, r, y]
                for y in range(d):
                    acc = 0.0
                    for x in range(d):
                        acc += jp[o, r, x] * hinv[p, x, y]
                    tmp[r, y] = acc
            for t in range(ptr[p], ptr[p + 1]):
                c0 = colof[frame_sorted[t]] * b
                for r in range(k):
                    for y in range(b):
                        acc = 0.0
                        for x in range(d):
                            acc += tmp[r, x] * hfp[t, y, x]
                        bm[a * k + r, c0 + y] -= acc
        for a in range(x1 - x0):
            x = xobs[x0 + a]
            for r in range(kx):
                row = nobs * k + a * kx + r
                flat[row] = base + x * kx + r
                for y in range(b):
                    bm[row, y] = jxf[x, r, y]
        sig = np.zeros((nh * b, nh * b))
        for a in range(nh):
            for c in range(nh):
                if not read_block(colptr, rowind, iperm, slot_pos, slot_stride, panels,
                                  hood[a], hood[c], blk):
                    raise ValueError("a block of the frames' covariance is missing")
                for r in range(b):
                    for y in range(b):
                        sig[a * b + r, c * b + y] = blk[r, y]
        q = _sandwich(bm, sig, nobs, k, b, fobs[o0:o1], point, ptr, frame_sorted, colof)
        for a in range(nobs):
            oa = fobs[o0 + a]
            p = point[oa]
            for c in range(a, nobs):
                oc = fobs[o0 + c]
                if point[oc] != p:
                    continue
                for r in range(k):
                    for y in range(d):
                        acc = 0.0
                        for x in range(d):
                            acc += jp[oa, r, x] * hinv[p, x, y]
                        tmp[r, y] = acc
                for r in range(k):
                    for s in range(k):
                        acc = 0.0
                        for y in range(d):
                            acc += tmp[r, y] * jp[oc, s, y]
                        q[a * k + r, c * k + s] += acc
                        if c != a:
                            q[c * k + s, a * k + r] += acc
        for r in range(nr):
            for s in range(r + 1, nr):
                n = _emit(e, flat[r], flat[s], q[r, s], oi, oj, oq, n)
    return n


def frame_pairs(factor: SchurFactor, layout: FlatLayout,
                frames: np.ndarray) -> Iterator[Triplets]:
    """(i, j, q_ij) of every two rows on one of the system frames `frames` (image rows of
    its observations and extra rows tied to it), i < j, in chunks of frames."""
    s, lin = factor.system, factor.lin
    frames = np.unique(np.asarray(frames, np.int64))
    if not len(frames):
        return
    k = layout.k
    kx = layout.kx if layout.mx else 0
    e = border_factor(factor, layout)
    fptr, fobs = _by_frame(s.frame, s.nf)
    xptr, xobs = _by_frame(s.x_frame, s.nf) if layout.mx else (
        np.zeros(s.nf + 1, np.int64), np.zeros(0, np.int64))
    jxf = lin.jxf if layout.mx else np.zeros((0, 0, s.b))
    rows = np.diff(fptr)[frames] * k + np.diff(xptr)[frames] * kx
    # the frames that see the points of each frame: Sigma is needed between every two
    need_r, need_c = [], []
    for f in frames:
        obs = fobs[fptr[f]:fptr[f + 1]]
        pts = np.unique(s.point[obs])
        hood = np.unique(np.concatenate(
            [s.frame_sorted[s.ptr[p]:s.ptr[p + 1]] for p in pts] + [[f]]))
        rr, cc = np.meshgrid(hood, hood, indexing="ij")
        low = rr > cc
        need_r.append(rr[low])
        need_c.append(cc[low])
    sel = selected_inverse_including(factor.chol, np.concatenate(need_r),
                                     np.concatenate(need_c))
    look = block_lookup(sel)
    base = layout.m * k + len(layout.ctrl_sel)  # the first extra row
    hinv = factor.hpp_inv
    pairs = rows * (rows - 1) // 2
    lo = 0
    while lo < len(frames):
        hi = lo + max(1, int(np.searchsorted(np.cumsum(pairs[lo:]), 4 * CHUNK)))
        size = int(pairs[lo:hi].sum())
        oi, oj = np.empty(size, np.int64), np.empty(size, np.int64)
        oq = np.empty(size)
        n = _frame_pairs(frames[lo:hi], fptr, fobs, xptr, xobs, s.ptr, s.frame_sorted,
                         s.point, lin.jf, lin.jp, hinv, factor.hfp, jxf, e, k, kx, base,
                         *look, oi, oj, oq)
        yield oi[:n], oj[:n], oq[:n]
        lo = hi


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
            assert lin.jxf is not None and lin.jxg is not None
            if s.x_frame[x] >= 0:
                gf[s.x_frame[x], :, c] += lin.jxf[x, r]
            gg[:, c] += lin.jxg[x, r]
    if factor.has_border:
        return layout.flat(*factor.apply_A(*factor.solve_normal(gf, gp, gg)))
    return layout.flat(*factor.apply_A(*factor.solve_normal(gf, gp)))
