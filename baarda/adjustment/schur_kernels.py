"""numba kernels for the point-eliminated (Schur) normal equations.

Observations that tie one frame (photo or model, b unknowns) to one point (d unknowns)
are sorted by point; `ptr` delimits each point's observations.  For every point the
kernels loop over its ordered observation pairs (a, c) with frame[a] >= frame[c]; the
reduced system S is stored in the lower block triangle of a BlockPattern, `pair_slot`
gives the storage slot of block (frame[a], frame[c]) for each such pair and
`pair_tr` tells whether the stored block is its transpose.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from baarda.linalg._jit import kernel, parallel_kernel


@kernel
def count_pairs(ptr, frame):
    n = 0
    for j in range(len(ptr) - 1):
        for a in range(ptr[j], ptr[j + 1]):
            for c in range(ptr[j], ptr[j + 1]):
                if frame[a] >= frame[c]:
                    n += 1
    return n


@kernel
def _chol_inv(h, out_l, out_inv):
    """Cholesky factor and inverse of a small SPD matrix; returns False if not SPD.

    A pivot is compared with its own diagonal entry (the test is invariant to the scale of
    each unknown): a coordinate held by a large direct weight (fixed control, sigma 0) does
    not make the other coordinates of its point look singular."""
    d = h.shape[0]
    for i in range(d):
        for j in range(i + 1):
            s = h[i, j]
            for k in range(j):
                s -= out_l[i, k] * out_l[j, k]
            if i == j:
                if s <= 1e-12 * h[i, i] or s <= 0.0:
                    return False
                out_l[i, i] = np.sqrt(s)
            else:
                out_l[i, j] = s / out_l[j, j]
        for j in range(i + 1, d):
            out_l[i, j] = 0.0
    # inverse of L, then L^-T L^-1
    li = np.zeros((d, d))
    for i in range(d):
        li[i, i] = 1.0 / out_l[i, i]
        for j in range(i):
            s = 0.0
            for k in range(j, i):
                s -= out_l[i, k] * li[k, j]
            li[i, j] = s / out_l[i, i]
    for i in range(d):
        for j in range(d):
            s = 0.0
            for k in range(max(i, j), d):
                s += li[k, i] * li[k, j]
            out_inv[i, j] = s
    return True


def _frame_part_of(i, f, jf, w, e, hff, gf):
    """Observation i's terms of its frame f: Jf^T W Jf into hff[f], Jf^T W e into gf[f]."""
    k, b = jf.shape[1], jf.shape[2]
    for r in range(k):
        wr = w[i, r]
        if wr == 0.0:
            continue
        er = wr * e[i, r]
        for p in range(b):
            wp = wr * jf[i, r, p]
            gf[f, p] += jf[i, r, p] * er
            for q in range(b):
                hff[f, p, q] += wp * jf[i, r, q]


def _point_part_of(i, a, j, jf, jp, w, e, hfp, hpp, gp):
    """Observation i's terms of its point j (sorted position a): Jf^T W Jp into hfp[a],
    Jp^T W Jp into hpp[j], Jp^T W e into gp[j]."""
    k, b = jf.shape[1], jf.shape[2]
    d = jp.shape[2]
    for r in range(k):
        wr = w[i, r]
        if wr == 0.0:
            continue
        for p in range(b):
            wp = wr * jf[i, r, p]
            for q in range(d):
                hfp[a, p, q] += wp * jp[i, r, q]
        for p in range(d):
            wp = wr * jp[i, r, p]
            gp[j, p] += wp * e[i, r]
            for q in range(d):
                hpp[j, p, q] += wp * jp[i, r, q]


# inlined into assemble and assemble_parallel: each sum in the same order in both
_frame_part = kernel(_frame_part_of, inline="always")
_point_part = kernel(_point_part_of, inline="always")


@kernel
def assemble(order, frame, point_of_sorted, jf, jp, w, e, hfp, hff, gf, hpp, gp):
    """Normal-equation pieces of the frame-point observations, with explicit loops.

    Observations are visited in point order (`order`); hfp[a] (b, d) is stored at the
    sorted position a.  Adds Jf^T W Jf to hff (nf, b, b), Jf^T W e to gf (nf, b),
    Jp^T W Jp to hpp (np, d, d) and Jp^T W e to gp (np, d).
    """
    for a in range(len(order)):
        i = order[a]
        _frame_part(i, frame[i], jf, w, e, hff, gf)
        _point_part(i, a, point_of_sorted[a], jf, jp, w, e, hfp, hpp, gp)
    return 0


@parallel_kernel
def assemble_parallel(order, ptr, frame_ptr, frame_obs, jf, jp, w, e, hfp, hff, gf, hpp, gp):
    """`assemble` on numba's threads, every sum in the serial loop's order (the same numbers
    to the last bit): the point parts point by point (ptr: each point's observations in
    sorted order), the frame parts frame by frame, each frame's observations in sorted
    order (frame_obs[frame_ptr[f]:...])."""
    for j in prange(len(ptr) - 1):
        for a in range(ptr[j], ptr[j + 1]):
            _point_part(order[a], a, j, jf, jp, w, e, hfp, hpp, gp)
    for f in prange(len(frame_ptr) - 1):
        for x in range(frame_ptr[f], frame_ptr[f + 1]):
            _frame_part(order[frame_obs[x]], f, jf, w, e, hff, gf)
    return 0


def _inline(fn):
    """A kernel inlined into its callers, where literal sizes become loop bounds the compiler
    unrolls (the photo's 6 and the point's 3 unknowns: the same operations in the same order,
    so the same numbers, a third faster)."""
    return kernel(fn, inline="always")


@_inline
def _terms(hfp, hinv, gpj, a, t, g, b, d):
    """t[a] = Hfp_a Hpp^-1 (b, d) and g[a] = t[a] gp_j (b,) of observation a of a point."""
    for p in range(b):
        for q in range(d):
            acc = 0.0
            for r in range(d):
                acc += hfp[a, p, r] * hinv[r, q]
            t[a, p, q] = acc
        x = 0.0
        for q in range(d):
            x += t[a, p, q] * gpj[q]
        g[a, p] = x


@_inline
def _pair_term(values, s, tr, t, hfp, a, c, b, d):
    """values[s] -= t[a] Hfp_c^T (stored transposed when tr): one observation pair's term
    of S."""
    for p in range(b):
        for q in range(b):
            acc = 0.0
            for r in range(d):
                acc += t[a, p, r] * hfp[c, q, r]
            if tr:
                values[s, q, p] -= acc
            else:
                values[s, p, q] -= acc


@_inline
def _observation_terms(hfp, hinv, gpj, a, t, g, b, d):
    """_terms, with literal sizes for a photo and a point (b = 6, d = 3), and for a photo
    with its camera's f, k1, k2 (b = 9: BAL)."""
    if b == 6 and d == 3:
        _terms(hfp, hinv, gpj, a, t, g, 6, 3)
    elif b == 9 and d == 3:
        _terms(hfp, hinv, gpj, a, t, g, 9, 3)
    else:
        _terms(hfp, hinv, gpj, a, t, g, b, d)


@_inline
def _subtract_pair(values, s, tr, t, hfp, a, c, b, d):
    """_pair_term, with literal sizes for a photo and a point (b = 6, d = 3), and for a
    photo with its camera's f, k1, k2 (b = 9: BAL)."""
    if b == 6 and d == 3:
        _pair_term(values, s, tr, t, hfp, a, c, 6, 3)
    elif b == 9 and d == 3:
        _pair_term(values, s, tr, t, hfp, a, c, 9, 3)
    else:
        _pair_term(values, s, tr, t, hfp, a, c, b, d)


@kernel
def reduce_points(ptr, frame, hfp, hpp, gp, gf, values, diag_slot, hff, pair_slot, pair_tr,
                  hpp_l, hpp_inv, bad):
    """Form S = Hff - sum_j Hfp_j Hpp_j^-1 Hpf_j and the reduced right-hand side, point by
    point on one thread (small blocks: numba's threads are not started, so a process that
    adjusts small blocks can still fork; reduce_points_parallel gives the same numbers).

    hfp (m, b, d) per observation (sorted by point), frame (m,) sorted likewise; hpp
    (np, d, d) and gp (np, d) per point; hff (nf, b, b) frame diagonal blocks; gf (nf, b)
    is reduced in place.  Writes Cholesky factors and inverses of Hpp; bad[j] = 1 for a
    point whose Hpp is not positive definite.
    """
    nf = hff.shape[0]
    b = hff.shape[1]
    d = hpp.shape[1]
    for f in range(nf):
        s = diag_slot[f]
        for r in range(b):
            for c in range(b):
                values[s, r, c] += hff[f, r, c]
    k = 0
    t = np.empty((hfp.shape[0], b, d))
    g = np.empty((hfp.shape[0], b))
    for j in range(len(ptr) - 1):
        lo, hi = ptr[j], ptr[j + 1]
        if not _chol_inv(hpp[j], hpp_l[j], hpp_inv[j]):
            bad[j] = 1
            for a in range(lo, hi):
                for c in range(lo, hi):
                    if frame[a] >= frame[c]:
                        k += 1
            continue
        for a in range(lo, hi):
            _observation_terms(hfp, hpp_inv[j], gp[j], a, t, g, b, d)
            for p in range(b):
                gf[frame[a], p] -= g[a, p]
        for a in range(lo, hi):
            for c in range(lo, hi):
                if frame[a] >= frame[c]:
                    _subtract_pair(values, pair_slot[k], pair_tr[k], t, hfp, a, c, b, d)
                    k += 1
    return d


@kernel
def pair_observations(ptr, frame, n):
    """(a, c, point) of every frame pair (frame[a] >= frame[c]) in the kernels' loop order:
    the sorted positions of its two observations and their point."""
    pa = np.empty(n, np.int64)
    pc = np.empty(n, np.int64)
    pj = np.empty(n, np.int64)
    k = 0
    for j in range(len(ptr) - 1):
        for a in range(ptr[j], ptr[j + 1]):
            for c in range(ptr[j], ptr[j + 1]):
                if frame[a] >= frame[c]:
                    pa[k], pc[k], pj[k] = a, c, j
                    k += 1
    return pa, pc, pj


@parallel_kernel
def reduce_points_parallel(ptr, point, hfp, hpp, gp, gf, values, hff, slot_diag, slot_ptr,
                           slot_pairs, pair_a, pair_c, pair_point, pair_tr, frame_ptr,
                           frame_obs, hpp_l, hpp_inv, bad):
    """Form S = Hff - sum_j Hfp_j Hpp_j^-1 Hpf_j and the reduced right-hand side on numba's
    threads, every sum taken in the order of the serial loop over points (reduce_points), so
    the result is the same to the last bit for any number of threads.

    hfp (m, b, d) per observation (sorted by point; point (m,) their points), hpp (np, d, d)
    and gp (np, d) per point; hff (nf, b, b) frame diagonal blocks; gf (nf, b) is reduced in
    place.  Writes Cholesky factors and inverses of Hpp; bad[j] = 1 for a point whose Hpp is
    not positive definite.

    Points first (each its Hpp^-1 and t = Hfp Hpp^-1 of its observations); then each frame's
    right-hand side, its observations in sorted order (frame_obs[frame_ptr[f]:...]); then each
    stored block of S: the frame's Hff on a diagonal block (slot_diag >= 0), minus its
    observation pairs in loop order (slot_pairs[slot_ptr[s]:...]).
    """
    b = hff.shape[1]
    d = hpp.shape[1]
    m = hfp.shape[0]
    t = np.empty((m, b, d))
    g = np.empty((m, b))
    for j in prange(len(ptr) - 1):
        if not _chol_inv(hpp[j], hpp_l[j], hpp_inv[j]):
            bad[j] = 1
            continue
        for a in range(ptr[j], ptr[j + 1]):
            _observation_terms(hfp, hpp_inv[j], gp[j], a, t, g, b, d)
    for f in prange(len(frame_ptr) - 1):
        for i in range(frame_ptr[f], frame_ptr[f + 1]):
            a = frame_obs[i]
            if bad[point[a]]:
                continue
            for p in range(b):
                gf[f, p] -= g[a, p]
    for s in prange(len(slot_ptr) - 1):
        f = slot_diag[s]
        if f >= 0:
            for r in range(b):
                for c in range(b):
                    values[s, r, c] += hff[f, r, c]
        for i in range(slot_ptr[s], slot_ptr[s + 1]):
            k = slot_pairs[i]
            if bad[pair_point[k]]:
                continue
            _subtract_pair(values, s, pair_tr[k], t, hfp, pair_a[k], pair_c[k], b, d)
    return d


@kernel
def back_substitute(ptr, frame, hfp, hpp_inv, gp, xf):
    """Point unknowns x_p = Hpp^-1 (g_p - sum_a Hpf_a x_f[f_a]); gp (np, d, q), xf (nf, b, q)."""
    npnt = len(ptr) - 1
    d = hpp_inv.shape[1]
    b = hfp.shape[1]
    q = gp.shape[2]
    xp = np.zeros((npnt, d, q))
    r = np.empty((d, q))
    for j in range(npnt):
        for p in range(d):
            for c in range(q):
                r[p, c] = gp[j, p, c]
        for a in range(ptr[j], ptr[j + 1]):
            f = frame[a]
            if q == 1:
                for p in range(d):
                    acc = 0.0
                    for s in range(b):
                        acc += hfp[a, s, p] * xf[f, s, 0]
                    r[p, 0] -= acc
            else:  # many columns (a border): the columns innermost, contiguous
                for p in range(d):
                    for s in range(b):
                        h = hfp[a, s, p]
                        for c in range(q):
                            r[p, c] -= h * xf[f, s, c]
        if q == 1:
            for p in range(d):
                acc = 0.0
                for s in range(d):
                    acc += hpp_inv[j, p, s] * r[s, 0]
                xp[j, p, 0] = acc
        else:
            for p in range(d):
                for s in range(d):
                    h = hpp_inv[j, p, s]
                    for c in range(q):
                        xp[j, p, c] += h * r[s, c]
    return xp


@kernel
def point_covariances(ptr, frame, hfp, hpp_inv, sel, pair_slot, pair_tr, order):
    """Sigma_pf for every observation (m, d, b), in the observations' own order (order[a]:
    the observation at sorted position a), and Sigma_pp per point (np, d, d).

    sel: selected inverse of S in pattern storage (same slots as S).
        Sigma_pf[a] = -Hpp^-1 sum_c Hpf_c Sigma_ff[frame c, frame a]
        Sigma_pp    =  Hpp^-1 - sum_a Sigma_pf[a] Hfp_a Hpp^-1
    """
    m = hfp.shape[0]
    b = hfp.shape[1]
    d = hfp.shape[2]
    npnt = len(ptr) - 1
    spf = np.zeros((m, d, b))
    spp = np.zeros((npnt, d, d))
    acc = np.zeros((m, d, b))
    tmp = np.empty((d, d))
    k = 0
    for j in range(npnt):
        lo, hi = ptr[j], ptr[j + 1]
        for a in range(lo, hi):
            for c in range(lo, hi):
                if frame[a] < frame[c]:
                    continue
                s = pair_slot[k]
                tr = pair_tr[k]
                # blk = Sigma[f_a, f_c] = sel[s] (or its transpose)
                # acc[a] += Hpf_c Sigma[f_c, f_a] = hfp[c]^T blk^T
                # acc[c] += Hpf_a Sigma[f_a, f_c] = hfp[a]^T blk   (frames differ)
                for p in range(d):
                    for q in range(b):
                        x = 0.0
                        for r in range(b):
                            blk_qr = sel[s, r, q] if tr else sel[s, q, r]  # blk[q, r]
                            x += hfp[c, r, p] * blk_qr
                        acc[a, p, q] += x
                if frame[a] != frame[c]:
                    for p in range(d):
                        for q in range(b):
                            x = 0.0
                            for r in range(b):
                                blk_rq = sel[s, q, r] if tr else sel[s, r, q]  # blk[r, q]
                                x += hfp[a, r, p] * blk_rq
                            acc[c, p, q] += x
                k += 1
        hinv = hpp_inv[j]
        for p in range(d):
            for q in range(d):
                tmp[p, q] = hinv[p, q]
        for a in range(lo, hi):
            o = order[a]
            for p in range(d):
                for q in range(b):
                    x = 0.0
                    for r in range(d):
                        x += hinv[p, r] * acc[a, r, q]
                    spf[o, p, q] = -x
            # tmp -= spf[a] @ hfp[a] @ hinv
            for p in range(d):
                for q in range(d):
                    x = 0.0
                    for r in range(b):
                        y = 0.0
                        for t in range(d):
                            y += hfp[a, r, t] * hinv[t, q]
                        x += spf[o, p, r] * y
                    tmp[p, q] -= x
        for p in range(d):
            for q in range(d):
                spp[j, p, q] = tmp[p, q]
    return spf, spp


@kernel
def reduce_rhs_columns(ptr, frame, hfp, hpp_inv, gp, red):
    """red (nf, b, q) -= sum_a Hfp_a Hpp_j^-1 gp_j over the observations a of each point j
    (sorted by point, frame (m,) sorted likewise): the reduced right-hand side of q columns
    (the border's columns of a self-calibration: q = number of camera parameters)."""
    b, d = hfp.shape[1], hfp.shape[2]
    q = gp.shape[2]
    u = np.empty((d, q))
    for j in range(len(ptr) - 1):
        for r in range(d):
            for c in range(q):
                acc = 0.0
                for e in range(d):
                    acc += hpp_inv[j, r, e] * gp[j, e, c]
                u[r, c] = acc
        for a in range(ptr[j], ptr[j + 1]):
            f = frame[a]
            for p in range(b):
                for r in range(d):
                    h = hfp[a, p, r]
                    for c in range(q):
                        red[f, p, c] -= h * u[r, c]


@kernel
def observation_cofactors(frame, point, jf, jp, sff, spf, spp):
    """Cofactor blocks (m, k, k) of the adjusted frame-point observations with the globals
    held: q = Jf Sff Jf' + Jp Spp Jp' + C + C', C = Jp Spf Jf', from the selected inverse's
    diagonal frame blocks sff (nf, b, b), Spf per observation (m, d, b) and Spp per point
    (np, d, d), row by row (no (m, b, b) copy of the frame blocks); each product summed in
    the order of a matrix product, left to right."""
    m, k, b = jf.shape
    d = jp.shape[2]
    q = np.empty((m, k, k))
    t = np.empty((k, b))
    u = np.empty((k, d))
    x = np.empty((k, b))
    for i in range(m):
        f = frame[i]
        j = point[i]
        for r in range(k):
            for c in range(b):
                acc = 0.0
                for s in range(b):
                    acc += jf[i, r, s] * sff[f, s, c]
                t[r, c] = acc
            for c in range(d):
                acc = 0.0
                for s in range(d):
                    acc += jp[i, r, s] * spp[j, s, c]
                u[r, c] = acc
            for c in range(b):
                acc = 0.0
                for s in range(d):
                    acc += jp[i, r, s] * spf[i, s, c]
                x[r, c] = acc
        for r in range(k):
            for c in range(k):
                a1 = 0.0
                for s in range(b):
                    a1 += t[r, s] * jf[i, c, s]
                a2 = 0.0
                for s in range(d):
                    a2 += u[r, s] * jp[i, c, s]
                q[i, r, c] = a1 + a2
        for r in range(k):
            for c in range(k):
                c1 = 0.0
                for s in range(b):
                    c1 += x[r, s] * jf[i, c, s]
                c2 = 0.0
                for s in range(b):
                    c2 += x[c, s] * jf[i, r, s]
                q[i, r, c] += c1 + c2
    return q
