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
from numba import njit


@njit(cache=True)
def count_pairs(ptr, frame):
    n = 0
    for j in range(len(ptr) - 1):
        for a in range(ptr[j], ptr[j + 1]):
            for c in range(ptr[j], ptr[j + 1]):
                if frame[a] >= frame[c]:
                    n += 1
    return n


@njit(cache=True)
def list_pairs(ptr, frame, n):
    """Frame pairs (rows >= cols) in the kernels' loop order."""
    rows = np.empty(n, np.int64)
    cols = np.empty(n, np.int64)
    k = 0
    for j in range(len(ptr) - 1):
        for a in range(ptr[j], ptr[j + 1]):
            for c in range(ptr[j], ptr[j + 1]):
                if frame[a] >= frame[c]:
                    rows[k] = frame[a]
                    cols[k] = frame[c]
                    k += 1
    return rows, cols


@njit(cache=True)
def _chol_inv(h, out_l, out_inv):
    """Cholesky factor and inverse of a small SPD matrix; returns False if not SPD."""
    d = h.shape[0]
    scale = 0.0
    for i in range(d):
        scale = max(scale, abs(h[i, i]))
    for i in range(d):
        for j in range(i + 1):
            s = h[i, j]
            for k in range(j):
                s -= out_l[i, k] * out_l[j, k]
            if i == j:
                if s <= 1e-12 * scale or s <= 0.0:
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


@njit(cache=True)
def reduce_points(ptr, frame, hfp, hpp, gp, gf, values, diag_slot, hff, pair_slot, pair_tr,
                  hpp_l, hpp_inv, bad):
    """Form S = Hff - sum_j Hfp_j Hpp_j^-1 Hpf_j and the reduced right-hand side.

    hfp (m, b, d) per observation; hpp (np, d, d) and gp (np, d) per point; hff (nf, b, b)
    frame diagonal blocks; gf (nf, b) is reduced in place.  Writes Cholesky factors and
    inverses of Hpp; bad[j] = 1 for a point whose Hpp is not positive definite.
    """
    nf = hff.shape[0]
    b = hff.shape[1]
    for f in range(nf):
        s = diag_slot[f]
        for r in range(b):
            for c in range(b):
                values[s, r, c] += hff[f, r, c]
    k = 0
    npnt = len(ptr) - 1
    d = hpp.shape[1]
    for j in range(npnt):
        ok = _chol_inv(hpp[j], hpp_l[j], hpp_inv[j])
        if not ok:
            bad[j] = 1
        lo, hi = ptr[j], ptr[j + 1]
        for a in range(lo, hi):
            if not ok:
                continue
            t = hfp[a] @ hpp_inv[j]  # (b, d)
            gf[frame[a]] -= t @ gp[j]
            for c in range(lo, hi):
                if frame[a] < frame[c]:
                    continue
                blk = t @ hfp[c].T
                s = pair_slot[k]
                if pair_tr[k]:
                    for r in range(b):
                        for q in range(b):
                            values[s, q, r] -= blk[r, q]
                else:
                    for r in range(b):
                        for q in range(b):
                            values[s, r, q] -= blk[r, q]
                k += 1
        if not ok:
            for a in range(lo, hi):
                for c in range(lo, hi):
                    if frame[a] >= frame[c]:
                        k += 1
    return d


@njit(cache=True)
def back_substitute(ptr, frame, hfp, hpp_inv, gp, xf):
    """Point unknowns x_p = Hpp^-1 (g_p - sum_a Hpf_a x_f[frame a]); xf (nf, b) or (nf, b, q)."""
    npnt = len(ptr) - 1
    d = hpp_inv.shape[1]
    q = gp.shape[2]
    xp = np.zeros((npnt, d, q))
    for j in range(npnt):
        r = gp[j].copy()
        for a in range(ptr[j], ptr[j + 1]):
            r -= hfp[a].T @ xf[frame[a]]
        xp[j] = hpp_inv[j] @ r
    return xp


@njit(cache=True)
def point_covariances(ptr, frame, hfp, hpp_inv, sel, pair_slot, pair_tr):
    """Sigma_pf for every observation (m, d, b) and Sigma_pp per point (np, d, d).

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
    k = 0
    for j in range(npnt):
        lo, hi = ptr[j], ptr[j + 1]
        acc = np.zeros((hi - lo, d, b))
        for a in range(lo, hi):
            for c in range(lo, hi):
                if frame[a] < frame[c]:
                    continue
                s = pair_slot[k]
                blk = sel[s].T.copy() if pair_tr[k] else sel[s].copy()  # Sigma[f_a, f_c]
                # ordered pair (a, c): acc[a] += Hpf_c Sigma[f_c, f_a] = Hpf_c blk^T; the
                # mirror pair (c, a) is visited separately only when frames are equal
                acc[a - lo] += hfp[c].T @ blk.T
                if frame[a] != frame[c]:
                    acc[c - lo] += hfp[a].T @ blk
                k += 1
        tmp = hpp_inv[j].copy()
        for a in range(lo, hi):
            spf[a] = -hpp_inv[j] @ acc[a - lo]
            tmp -= spf[a] @ hfp[a] @ hpp_inv[j]
        spp[j] = tmp
    return spf, spp
