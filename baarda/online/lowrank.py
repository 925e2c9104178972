"""Observations added since the last factorisation, as a low-rank update of it.

The last factorisation holds the normal equations N0 of the block at its solution x0.  Every
observation component added since (r scalar rows) is linearised at x0 and, where it brings
unknowns the factorisation does not have (a new point, a new photo), at their approximations
y0:  e = l - f(x0, y0) = a dx + b dy + eps,  eps with variance sigma^2.  The adjustment of
the block with them is then, exactly for this linearisation (one Gauss-Newton step from x0
with every observation), a small problem in the space of the r new rows.  The old
observations' gradient is zero at x0, so they act on dx as a prior with cofactor N0^-1, and

    H = N0^-1 A^T        (n x r: one solve with the factor per new row)
    C = R + A H          (r x r, R = diag(sigma^2): cofactor of the misclosures e)
    G = B^T C^-1 B       (the new unknowns' normal matrix; singular: not determined)
    W = C^-1 - C^-1 B G^-1 B^T C^-1

    dy = G^-1 B^T C^-1 e,  dx = H W e
    v  = -R W e                          (residuals of the new rows, adjusted - observed)
    Qvv = R W R                          (their cofactors after inclusion)
    Q_xx = N0^-1 - H W H^T               (the old unknowns' cofactors)

so an old observation j with Jacobian row a_j has v_j = v0_j + a_j dx and adjusted cofactor
q_j = q0_j - (a_j H) W (a_j H)^T.  Only solves with the factor and r x r matrices: no
cofactor block beyond what the new rows touch (tests/online/test_lowrank.py checks every
formula against the dense adjustment).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from baarda.adjustment.schur import SchurFactor
from baarda.errors import GeometryError

UNDETERMINED = 1e-8  # smallest eigenvalue of the scaled G: below it, new unknowns not determined


KY = 9  # new unknowns a row can touch: a photo's six and a point's three


@dataclass(frozen=True)
class Rows:
    """k scalar observation rows linearised at the factorisation's estimate.

    frame/point: the photo and the eliminated point of the factorisation each row depends on
    (-1: none), with their Jacobian rows jf (k, 6) and jp (k, 3); jg (k, ng) the global
    unknowns; ycol (k, ky) the columns among the new unknowns (-1: none) with jy (k, ky);
    sigma (k,) a-priori standard deviations; e (k,) misclosures observed - predicted."""

    frame: np.ndarray
    jf: np.ndarray
    point: np.ndarray
    jp: np.ndarray
    jg: np.ndarray
    ycol: np.ndarray
    jy: np.ndarray
    sigma: np.ndarray
    e: np.ndarray

    def __len__(self) -> int:
        return len(self.sigma)


GATHER = 200_000  # k q above this: rows grouped by unknown block, no (k, b, q) gather


def empty_rows(ng: int) -> Rows:
    return Rows(np.zeros(0, np.int64), np.zeros((0, 6)), np.zeros(0, np.int64),
                np.zeros((0, 3)), np.zeros((0, ng)), np.zeros((0, KY), np.int64),
                np.zeros((0, KY)), np.zeros(0), np.zeros(0))


def times(rows: Rows, hf: np.ndarray, hp: np.ndarray, hg: np.ndarray) -> np.ndarray:
    """a H for the rows' Jacobians a (over the factorisation's unknowns) and q columns H in
    the factor's parts (nf, b, q), (np, d, q), (ng, q): (k, q)."""
    q = hf.shape[2]
    out = np.zeros((len(rows), q))
    f = np.flatnonzero(rows.frame >= 0)
    if len(f):
        out[f] += _block_times(rows.jf[f], rows.frame[f], hf)
    p = np.flatnonzero(rows.point >= 0)
    if len(p):
        out[p] += _block_times(rows.jp[p], rows.point[p], hp)
    if hg.shape[0]:
        out += rows.jg @ hg
    return out


def _block_times(j: np.ndarray, idx: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Row i of the result: j[i] @ h[idx[i]] ((k, b), (k,), (n, b, q) -> (k, q)).  Few rows:
    one einsum over the gathered blocks; many: one product per block they touch (the gather
    would copy k b q numbers)."""
    k, q = len(idx), h.shape[2]
    if k * q <= GATHER:
        return np.einsum("kb,kbq->kq", j, h[idx])
    out = np.empty((k, q))
    order = np.argsort(idx, kind="stable")
    blocks, start = np.unique(idx[order], return_index=True)
    stop = np.append(start[1:], k)
    for u, a, b in zip(blocks.tolist(), start.tolist(), stop.tolist(), strict=True):
        sel = order[a:b]
        out[sel] = j[sel] @ h[u]
    return out


def quad_diag(z: np.ndarray, w: np.ndarray) -> np.ndarray:
    """diag(z W z^T) for z (k, r), W (r, r) symmetric: ((z W) * z) summed over r (a matrix
    product, not einsum's r^2 loop per row)."""
    return np.sum((z @ w) * z, axis=1)


class LowRank:
    """The rows added since a factorisation and the small problem they make (module
    docstring).  `add` appends rows (their new unknowns numbered on from `ny`), `solution`
    gives the adjustment with all of them."""

    def __init__(self, factor: SchurFactor):
        self.factor = factor
        s = factor.system
        self.nf, self.np_, self.ng = s.nf, s.np, s.ng
        self.r = 0
        self.ny = 0
        self._cap = 0
        self.hf = np.zeros((s.nf, s.b, 0))
        self.hp = np.zeros((s.np, s.d, 0))
        self.hg = np.zeros((s.ng, 0))
        self.m = np.zeros((0, 0))
        self.sigma = np.zeros(0)
        self.e = np.zeros(0)
        self.b = np.zeros((0, 0))
        self.rows: list[Rows] = []
        self._sol: Solution | None = None

    # ------------------------------------------------------------ storage
    def _grow(self, r: int, ny: int) -> None:
        if r > self._cap:
            cap = max(2 * self._cap, r, 16)
            for name in ("hf", "hp"):
                old = getattr(self, name)
                new = np.zeros(old.shape[:2] + (cap,))
                new[:, :, :self.r] = old[:, :, :self.r]
                setattr(self, name, new)
            hg = np.zeros((self.ng, cap))
            hg[:, :self.r] = self.hg[:, :self.r]
            self.hg = hg
            m = np.zeros((cap, cap))
            m[:self.r, :self.r] = self.m[:self.r, :self.r]
            self.m = m
            for name in ("sigma", "e"):
                old = getattr(self, name)
                new = np.zeros(cap)
                new[:self.r] = old[:self.r]
                setattr(self, name, new)
            self._cap = cap
        if r > self.b.shape[0] or ny > self.b.shape[1]:
            b = np.zeros((max(self._cap, r), max(ny, 2 * self.b.shape[1], 16)))
            b[:self.r, :self.ny] = self.b[:self.r, :self.ny]
            self.b = b

    def columns(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """H = N0^-1 A^T of the rows so far, in the factor's parts."""
        r = self.r
        return self.hf[:, :, :r], self.hp[:, :, :r], self.hg[:, :r]

    # ------------------------------------------------------------ rows
    def rhs(self, rows: Rows) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A^T of the rows as right-hand sides (nf, b, k), (np, d, k), (ng, k)."""
        k = len(rows)
        s = self.factor.system
        gf = np.zeros((s.nf, s.b, k))
        gp = np.zeros((s.np, s.d, k))
        idx = np.arange(k)
        f = rows.frame >= 0
        gf[rows.frame[f], :, idx[f]] = rows.jf[f]
        p = rows.point >= 0
        gp[rows.point[p], :, idx[p]] = rows.jp[p]
        gg = np.ascontiguousarray(rows.jg.T) if s.ng else np.zeros((0, k))
        return gf, gp, gg

    def solve(self, rows: Rows) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """N0^-1 A^T of the rows: one solve with the factor for k columns."""
        gf, gp, gg = self.rhs(rows)
        out = self.factor.solve_normal(gf, gp, gg)
        xg = out[2] if len(out) == 3 else np.zeros((0, len(rows)))
        return out[0], out[1], xg

    def add(self, rows: Rows, ny: int) -> None:
        """Append the rows; `ny`: the number of new unknowns after them (their ycol are
        columns below it)."""
        k = len(rows)
        r0 = self.r
        self._grow(r0 + k, ny)
        hf, hp, hg = self.solve(rows)
        old = times(rows, *self.columns())  # (k, r0)
        own = times(rows, hf, hp, hg)  # (k, k)
        sl = slice(r0, r0 + k)
        self.hf[:, :, sl], self.hp[:, :, sl], self.hg[:, sl] = hf, hp, hg
        self.m[sl, :r0] = old
        self.m[:r0, sl] = old.T
        self.m[sl, sl] = 0.5 * (own + own.T)
        self.sigma[sl] = rows.sigma
        self.e[sl] = rows.e
        on = rows.ycol >= 0
        ri = np.broadcast_to(np.arange(k)[:, None], rows.ycol.shape)
        self.b[r0 + ri[on], rows.ycol[on]] = rows.jy[on]
        self.r, self.ny = r0 + k, max(self.ny, ny)
        self.rows.append(rows)
        self._sol = None

    def drop_last(self, k: int, ny: int) -> None:
        """Take back the last k rows (and the new unknowns from `ny` on)."""
        self.r -= k
        self.b[self.r:self.r + k, :] = 0.0
        self.b[:, ny:self.ny] = 0.0
        self.ny = ny
        self.rows.pop()
        self._sol = None

    # ------------------------------------------------------------ the small problem
    def solution(self) -> Solution:
        """The adjustment of the factorisation's block with every row so far."""
        if self._sol is None:
            self._sol = _solution(self)
        return self._sol

    def old_rows(self, rows: Rows, q0: np.ndarray, v0: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """(adjusted cofactors, residuals) of rows of the factorisation's own observations
        with all the rows so far: q0 - (a H) W (a H)^T and v0 + a dx."""
        if not self.r:
            return q0, v0
        sol = self.solution()
        z = times(rows, *self.columns())
        return q0 - quad_diag(z, sol.w), v0 + z @ sol.we


@dataclass(frozen=True)
class Solution:
    """The small problem solved: W, W e, residuals and their cofactors of the rows, the
    corrections of the factorisation's unknowns (dxf, dxp, dxg) and of the new ones (dy)."""

    w: np.ndarray
    we: np.ndarray
    v: np.ndarray
    qvv: np.ndarray  # (r, r)
    dxf: np.ndarray
    dxp: np.ndarray
    dxg: np.ndarray
    dy: np.ndarray
    qyy: np.ndarray  # (ny, ny) cofactors of the new unknowns


def _solution(lr: LowRank) -> Solution:
    r, ny = lr.r, lr.ny
    s2 = lr.sigma[:r] ** 2
    c = lr.m[:r, :r] + np.diag(s2)
    ci = cho_solve(cho_factor(c, lower=True), np.eye(r))
    b = lr.b[:r, :ny]
    e = lr.e[:r]
    if ny:
        cib = ci @ b
        g = b.T @ cib
        g = 0.5 * (g + g.T)
        scale = np.sqrt(np.maximum(np.diag(g), 1e-300))
        gs = g / np.outer(scale, scale)
        lam = np.linalg.eigvalsh(gs)
        if not lam[0] > UNDETERMINED * max(lam[-1], 1e-300):
            raise GeometryError("the new unknowns are not determined by these observations")
        gi = np.linalg.inv(gs) / np.outer(scale, scale)
        gi = 0.5 * (gi + gi.T)
        w = ci - cib @ gi @ cib.T
        dy = gi @ (cib.T @ e)
    else:
        w, dy, gi = ci, np.zeros(0), np.zeros((0, 0))
    w = 0.5 * (w + w.T)
    we = w @ e
    hf, hp, hg = lr.columns()
    return Solution(w=w, we=we, v=-s2 * we, qvv=s2[:, None] * w * s2[None, :],
                    dxf=hf @ we, dxp=hp @ we, dxg=hg @ we, dy=dy, qyy=gi)
