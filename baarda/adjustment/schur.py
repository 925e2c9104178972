"""Sparse normal equations with points eliminated by the Schur complement.

Unknowns: `n_frames` frames of `b` unknowns (photos: 6; independent models: 7 or 4) and
`n_points` points of `d` unknowns (3 or 2).  Observations come in two sets:

* frame-point observations, `k` rows each, tied to one frame and one point (image points,
  model coordinates);
* point observations, `kp` rows each, tied to one point (ground control);
* optionally, direct observations of frame unknowns (diagonal weights per frame unknown).

Weights are diagonal (1 / sigma^2, zero for a row that is not observed).  The reduced
frame system S is factored by the block Cholesky of baarda.linalg; its selected inverse
gives every covariance block that the residual cofactors need.  No matrix whose size
grows with the block is ever dense.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.adjustment import schur_kernels as kernels
from baarda.errors import GeometryError
from baarda.linalg import BlockCholesky, BlockPattern, NotPositiveDefinite
from baarda.linalg.threads import single_threaded_blas


@dataclass(frozen=True)
class Linearization:
    """Jacobians, weights and misclosures e = l - f(x0) at the current estimate."""

    jf: np.ndarray  # (m, k, b)
    jp: np.ndarray  # (m, k, d)
    w: np.ndarray  # (m, k)
    e: np.ndarray  # (m, k)
    jc: np.ndarray  # (mp, kp, d) point observations
    wc: np.ndarray  # (mp, kp)
    ec: np.ndarray  # (mp, kp)
    wf: np.ndarray | None = None  # (nf, b) weights of direct observations of frame unknowns
    ef: np.ndarray | None = None  # (nf, b) their misclosures (observed - current)

    @property
    def cost(self) -> float:
        """v'Pv: the weighted sum of squares of the misclosures."""
        c = float(np.sum(self.w * self.e**2) + np.sum(self.wc * self.ec**2))
        if self.wf is not None:
            c += float(np.sum(self.wf * self.ef**2))
        return c


class SchurSystem:
    """The structure of the reduced normal equations: fixed for a problem, never changed.

    `factorize(lin)` returns the numbers of one linearisation as a new SchurFactor.
    n_fixed: frame unknowns held by datum constraints (zero Jacobian columns plus a direct
    observation of weight wf): they are not unknowns of the model (bundle/free_network.py).
    """

    def __init__(self, n_frames: int, b: int, n_points: int, d: int,
                 frame: np.ndarray, point: np.ndarray, control_point: np.ndarray,
                 frame_names: list[str] | None = None, point_names: list[str] | None = None,
                 n_fixed: int = 0):
        self.nf, self.b, self.np, self.d = n_frames, b, n_points, d
        self.frame_names = frame_names or [str(i) for i in range(n_frames)]
        self.point_names = point_names or [str(i) for i in range(n_points)]
        frame = np.asarray(frame, np.int64)
        point = np.asarray(point, np.int64)
        self.order = np.argsort(point, kind="stable")  # observation order inside kernels
        self.frame_sorted = frame[self.order]
        self.point_sorted = point[self.order]
        self.frame, self.point = frame, point
        self.ptr = np.zeros(n_points + 1, np.int64)
        np.cumsum(np.bincount(point, minlength=n_points), out=self.ptr[1:])
        self.control_point = np.asarray(control_point, np.int64)
        npairs = kernels.count_pairs(self.ptr, self.frame_sorted)
        rows, cols = kernels.list_pairs(self.ptr, self.frame_sorted, npairs)
        self.pattern = BlockPattern.from_pairs(n_frames, b, rows, cols)
        self.pair_slot, self.pair_tr = self.pattern.slots(rows, cols)
        diag = np.arange(n_frames)
        self.diag_slot, _ = self.pattern.slots(diag, diag)
        self.n_fixed = int(n_fixed)

    @property
    def n_unknowns(self) -> int:
        return self.nf * self.b + self.np * self.d - self.n_fixed

    def factorize(self, lin: Linearization, damping: float = 0.0) -> SchurFactor:
        """Assemble the normal equations of `lin`, reduce them and factor S.

        damping: Levenberg-Marquardt lambda; the diagonal of N is multiplied by 1 + lambda.
        """
        return SchurFactor(self, lin, damping)


class SchurFactor:
    """The normal equations of one linearisation, points eliminated and S factored.

    Owned by whoever asked for it (an adjustment result keeps the one at its solution);
    the covariance blocks of the selected inverse are computed on first use and kept.
    """

    @single_threaded_blas
    def __init__(self, system: SchurSystem, lin: Linearization, damping: float = 0.0):
        s = self.system = system
        self.lin, self.damping = lin, float(damping)
        hff = np.zeros((s.nf, s.b, s.b))
        gf = np.zeros((s.nf, s.b))
        hpp = np.zeros((s.np, s.d, s.d))
        gp = np.zeros((s.np, s.d))
        self.hfp = np.zeros((len(s.order), s.b, s.d))
        kernels.assemble(s.order, s.frame, s.point_sorted, lin.jf, lin.jp, lin.w, lin.e,
                         self.hfp, hff, gf, hpp, gp)
        if lin.wf is not None:  # direct observations of frame unknowns (e.g. GNSS, datum)
            hff[:, np.arange(s.b), np.arange(s.b)] += lin.wf
            gf += lin.wf * lin.ef
        jcw = lin.jc * lin.wc[:, :, None]
        np.add.at(hpp, s.control_point, np.einsum("mkd,mke->mde", jcw, lin.jc))
        np.add.at(gp, s.control_point, np.einsum("mkd,mk->md", jcw, lin.ec))
        if damping:
            hff[:, np.arange(s.b), np.arange(s.b)] *= 1.0 + damping
            hpp[:, np.arange(s.d), np.arange(s.d)] *= 1.0 + damping
        self.gp = gp
        values = s.pattern.new_values()
        self.hpp_l = np.zeros_like(hpp)
        self.hpp_inv = np.zeros_like(hpp)
        bad = np.zeros(s.np, np.int8)
        kernels.reduce_points(s.ptr, s.frame_sorted, self.hfp, hpp, gp, gf, values,
                              s.diag_slot, hff, s.pair_slot, s.pair_tr,
                              self.hpp_l, self.hpp_inv, bad)
        if bad.any():
            names = [s.point_names[j] for j in np.flatnonzero(bad)[:10]]
            raise GeometryError(
                f"{int(bad.sum())} point(s) cannot be intersected (their rays are parallel or "
                f"too few): {', '.join(names)}")
        self.gf = gf
        self._sel = None
        self.chol = BlockCholesky(s.pattern)
        finite = np.isfinite(values).all(axis=(1, 2))
        if not finite.all():
            first = ~finite[s.diag_slot]
            raise GeometryError(
                "the normal equations overflow (coordinates, image coordinates or weights far "
                "too large: check their units)" + (
                    f"; first at {s.frame_names[int(np.argmax(first))]}" if first.any()
                    else ""))
        try:
            self.chol.factorize(values)
        except NotPositiveDefinite as err:
            raise GeometryError(
                f"the exterior orientation of {s.frame_names[err.block]} is not determined: "
                "the block has a datum defect or this photo is not connected well enough "
                "(check control and tie points)") from None

    @single_threaded_blas
    def step(self) -> tuple[np.ndarray, np.ndarray]:
        """Corrections to the frame (nf, b) and point (np, d) unknowns."""
        s = self.system
        xf = self.chol.solve(self.gf.reshape(-1)).reshape(s.nf, s.b)
        xp = kernels.back_substitute(s.ptr, s.frame_sorted, self.hfp, self.hpp_inv,
                                     self.gp[:, :, None], xf[:, :, None])
        return xf, xp[:, :, 0]

    # ------------------------------------------------------------ covariances
    @single_threaded_blas
    def covariances(self):
        """Selected inverse: Sigma_ff (pattern storage), Sigma_pf per observation, Sigma_pp."""
        if self._sel is None:
            s = self.system
            sel = self.chol.selected_inverse()
            values = sel.pattern_values()
            spf, spp = kernels.point_covariances(s.ptr, s.frame_sorted, self.hfp,
                                                 self.hpp_inv, values, s.pair_slot, s.pair_tr)
            inv = np.empty_like(s.order)
            inv[s.order] = np.arange(len(s.order))
            self._sel = (sel, values[s.diag_slot], spf[inv], spp)
        return self._sel

    def frame_covariance(self) -> np.ndarray:
        """(nf, b, b) cofactor blocks of the frame unknowns."""
        return self.covariances()[1]

    def point_covariance(self) -> np.ndarray:
        """(np, d, d) cofactor blocks of the point unknowns (marginal, not conditional)."""
        return self.covariances()[3]

    def adjusted_cofactors(self) -> tuple[np.ndarray, np.ndarray]:
        """Cofactor blocks of the adjusted observations: (m, k, k) and (mp, kp, kp)."""
        lin, system = self.lin, self.system
        _, sff, spf, spp = self.covariances()
        jf, jp = lin.jf, lin.jp
        sf = sff[system.frame]
        q = (jf @ sf @ np.swapaxes(jf, 1, 2)
             + jp @ spp[system.point] @ np.swapaxes(jp, 1, 2))
        cross = jp @ spf @ np.swapaxes(jf, 1, 2)
        q += cross + np.swapaxes(cross, 1, 2)
        qc = lin.jc @ spp[system.control_point] @ np.swapaxes(lin.jc, 1, 2)
        return q, qc

    def point_effect(self) -> tuple[np.ndarray, np.ndarray]:
        """Change of the observed point's unknowns per unit error of each observation row.

        (m, k, d) for frame-point observations and (mp, kp, d) for point observations:
        dX = Sigma_{X, x} a_i^T p_i, the column of N^-1 A^T P for that row, restricted to
        the point that the observation belongs to.
        """
        lin, system = self.lin, self.system
        _, _, spf, spp = self.covariances()
        g = (spf @ np.swapaxes(lin.jf, 1, 2) + spp[system.point] @ np.swapaxes(lin.jp, 1, 2))
        g = np.swapaxes(g, 1, 2) * lin.w[:, :, None]
        gc = np.swapaxes(spp[system.control_point] @ np.swapaxes(lin.jc, 1, 2), 1, 2)
        gc = gc * lin.wc[:, :, None]
        return g, gc

    # ---------------------------------------------------- general columns (H)
    def apply_AtP(self, h: np.ndarray, hc: np.ndarray):
        """A^T P [h; hc] for q columns: h (m, k, q), hc (mp, kp, q) -> (nf, b, q), (np, d, q)."""
        lin, s = self.lin, self.system
        q = h.shape[2]
        gf = np.zeros((s.nf, s.b, q))
        gp = np.zeros((s.np, s.d, q))
        hw = h * lin.w[:, :, None]
        np.add.at(gf, s.frame, np.einsum("mkb,mkq->mbq", lin.jf, hw))
        np.add.at(gp, s.point, np.einsum("mkd,mkq->mdq", lin.jp, hw))
        np.add.at(gp, s.control_point,
                  np.einsum("mkd,mkq->mdq", lin.jc, hc * lin.wc[:, :, None]))
        return gf, gp

    def _reduce_rhs(self, gf: np.ndarray, gp: np.ndarray) -> np.ndarray:
        """gf - sum Hfp Hpp^-1 gp for q columns, (nf, b, q)."""
        s = self.system
        t = np.einsum("mbd,mde->mbe", self.hfp, self.hpp_inv[s.point_sorted])
        red = gf.copy()
        np.add.at(red, s.frame_sorted, -np.einsum("mbd,mdq->mbq", t, gp[s.point_sorted]))
        return red

    @single_threaded_blas
    def solve_normal(self, gf: np.ndarray, gp: np.ndarray):
        """N^-1 [gf; gp] for q columns."""
        s = self.system
        q = gf.shape[2]
        red = self._reduce_rhs(gf, gp)
        xf = self.chol.solve(red.reshape(s.nf * s.b, q)).reshape(s.nf, s.b, q)
        xp = kernels.back_substitute(s.ptr, s.frame_sorted, self.hfp, self.hpp_inv,
                                     np.ascontiguousarray(gp), np.ascontiguousarray(xf))
        return xf, xp

    @single_threaded_blas
    def forward(self, gf: np.ndarray, gp: np.ndarray) -> np.ndarray:
        """W with W^T W = g^T N^-1 g for q columns (FOTEF: one forward substitution)."""
        s = self.system
        q = gf.shape[2]
        red = self._reduce_rhs(gf, gp)
        wf = self.chol.forward(red.reshape(s.nf * s.b, q))
        # Hpp = L L^T per point: the point part of the forward substitution is L^-1 gp
        wp = np.linalg.solve(self.hpp_l, gp)
        return np.concatenate([wp.reshape(s.np * s.d, q), wf.reshape(-1, q)])

    def apply_A(self, xf: np.ndarray, xp: np.ndarray):
        """A x for q columns: (m, k, q), (mp, kp, q)."""
        lin, s = self.lin, self.system
        rows = (np.einsum("mkb,mbq->mkq", lin.jf, xf[s.frame])
                + np.einsum("mkd,mdq->mkq", lin.jp, xp[s.point]))
        rows_c = np.einsum("mkd,mdq->mkq", lin.jc, xp[s.control_point])
        return rows, rows_c
