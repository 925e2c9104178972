"""The numbers of one linearisation of a SchurSystem (adjustment/schur_system.py, which
describes the unknowns, the observation sets and the elimination): the normal equations
assembled, the points eliminated, S factored, the global unknowns eliminated last, and
every cofactor the quality layer asks for from the selected inverse of S.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular

from baarda.adjustment import schur_kernels as kernels
from baarda.errors import GeometryError
from baarda.linalg import BlockCholesky, NotPositiveDefinite
from baarda.linalg.threads import single_threaded_blas

if TYPE_CHECKING:
    from baarda.adjustment.schur_system import Linearization, SchurSystem


# observations x k x b^2 above which the cofactor blocks of the observations are formed row
# by row (schur_kernels.observation_cofactors: the same products, without BLAS's fused
# multiply-adds) instead of by NumPy over a copy of a frame block per observation (32 MB);
# that kernel is compiled when a block this large first needs it, not on every first run
ROW_BY_ROW = 8_000_000


def _inner(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """sum over the first two axes of a[i, j, g] b[i, j, h]: (g, h), one BLAS product."""
    return a.reshape(-1, a.shape[2]).T @ b.reshape(-1, b.shape[2])


class SchurFactor:
    """The normal equations of one linearisation, points eliminated and S factored.

    Owned by whoever asked for it (an adjustment result keeps the one at its solution);
    the covariance blocks of the selected inverse are computed on first use and kept.
    Observation-side arguments and results come in three parts (frame-point rows, point
    rows, extra rows), unknown-side ones in three parts (frames, points, globals) when the
    system has global unknowns or extra observations, else in two.
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
        if s.parallel_assembly():
            kernels.assemble_parallel(s.order, s.ptr, s.frame_ptr, s.frame_obs, lin.jf, lin.jp,
                                      lin.w, lin.e, self.hfp, hff, gf, hpp, gp)
        else:  # the same numbers on one thread
            kernels.assemble(s.order, s.frame, s.point_sorted, lin.jf, lin.jp, lin.w, lin.e,
                             self.hfp, hff, gf, hpp, gp)
        if lin.wf is not None:  # direct observations of frame unknowns (e.g. GNSS, datum)
            hff[:, np.arange(s.b), np.arange(s.b)] += lin.wf
            gf += lin.wf * lin.ef
        if lin.wp is not None:  # held point coordinates
            hpp[:, np.arange(s.d), np.arange(s.d)] += lin.wp
            gp += lin.wp * lin.ep
        jcw = lin.jc * lin.wc[:, :, None]
        np.add.at(hpp, s.control_point, np.einsum("mkd,mke->mde", jcw, lin.jc))
        np.add.at(gp, s.control_point, np.einsum("mkd,mk->md", jcw, lin.ec))
        if s.mx:  # extra observations: their frame part
            xf = s.x_frame >= 0
            assert lin.jxf is not None and lin.wx is not None and lin.ex is not None
            jxw = lin.jxf[xf] * lin.wx[xf][:, :, None]
            np.add.at(hff, s.x_frame[xf], np.einsum("xkb,xkc->xbc", jxw, lin.jxf[xf]))
            np.add.at(gf, s.x_frame[xf], np.einsum("xkb,xk->xb", jxw, lin.ex[xf]))
        if s.ng:
            self._assemble_globals(lin)
        if damping:
            hff[:, np.arange(s.b), np.arange(s.b)] *= 1.0 + damping
            hpp[:, np.arange(s.d), np.arange(s.d)] *= 1.0 + damping
            if s.ng:
                self.hgg[np.arange(s.ng), np.arange(s.ng)] *= 1.0 + damping
        self.gp = gp
        values = s.pattern.new_values()
        self.hpp_l = np.zeros_like(hpp)
        self.hpp_inv = np.zeros_like(hpp)
        bad = np.zeros(s.np, np.int8)
        if s.parallel_reduction():
            kernels.reduce_points_parallel(
                s.ptr, s.point_sorted, self.hfp, hpp, gp, gf, values, hff, s.slot_diag,
                s.slot_ptr, s.slot_pairs, s.pair_a, s.pair_c, s.pair_point, s.pair_tr,
                s.frame_ptr, s.frame_obs, self.hpp_l, self.hpp_inv, bad)
        else:  # the same numbers on one thread
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
            raise GeometryError(self._undetermined(values, err.block), frame=err.block) from None
        if s.ng:
            self._eliminate_globals()

    def _undetermined(self, values: np.ndarray, k: int) -> str:
        """Why frame k's pivot failed, naming its unknowns whose columns are dependent (the
        null vector of its diagonal block of the reduced normal equations, after the points'
        elimination; held unknowns, of weight HOLD, are never among them)."""
        s = self.system
        names = s.column_names(k) if s.column_names is not None else None
        dep, n_null = dependent_columns(values[s.diag_slot[k]])
        if names is None or not dep:
            return (f"the exterior orientation of {s.frame_names[k]} is not determined: the "
                    "block has a datum defect or this photo is not connected well enough "
                    "(check control and tie points)")
        which = [names[i] for i in dep]
        if max(dep) < 6:  # the orientation alone: too few observations, or the datum
            return (f"the exterior orientation of {s.frame_names[k]} is not determined "
                    f"({', '.join(which)} move freely): the block has a datum defect or this "
                    "photo is not connected well enough (check control and tie points)")
        if len(which) == 1:
            return (f"{which[0]} is not determined by the observations of "
                    f"{s.frame_names[k]}: hold it fixed or add observations that determine it")
        return (f"{', '.join(which[:-1])} and {which[-1]} cannot be told apart ({n_null} "
                "combination(s) of them are not determined: their columns of the normal "
                f"equations are dependent in the observations of {s.frame_names[k]}; e.g. a "
                "flat block seen from above cannot separate the principal distance from the "
                "height of the photos, nor the principal point from their position): hold "
                "some of them fixed (--calibrate) or strengthen the geometry (relief, tilted "
                "or rotated photos, control)")

    # ----------------------------------------------------------- global unknowns
    def _assemble_globals(self, lin: Linearization) -> None:
        """Hgg (ng, ng), gg (ng,), Hfg (nf, b, ng), Hpg (np, d, ng) of the border."""
        s = self.system
        ng = s.ng
        hgg, gg = np.zeros((ng, ng)), np.zeros(ng)
        hfg, hpg = np.zeros((s.nf, s.b, ng)), np.zeros((s.np, s.d, ng))
        if lin.jg is not None and s.gcol.shape[1]:
            col = s.gcol
            jgw = lin.jg * lin.w[:, :, None]
            ok = col >= 0
            blk = np.einsum("mka,mkc->mac", jgw, lin.jg)
            both = ok[:, :, None] & ok[:, None, :]
            r = np.broadcast_to(col[:, :, None], blk.shape)[both]
            c = np.broadcast_to(col[:, None, :], blk.shape)[both]
            np.add.at(hgg, (r, c), blk[both])
            np.add.at(gg, col[ok], np.einsum("mka,mk->ma", jgw, lin.e)[ok])
            mi, ai = np.nonzero(ok)
            # (numpy's stubs reject a slice in ufunc.at's index tuple: type: ignore)
            np.add.at(hfg, (s.frame[mi], slice(None), col[mi, ai]),  # type: ignore[arg-type]
                      np.einsum("mkb,mk->mb", lin.jf[mi], jgw[mi, :, ai]))
            np.add.at(hpg, (s.point[mi], slice(None), col[mi, ai]),  # type: ignore[arg-type]
                      np.einsum("mkd,mk->md", lin.jp[mi], jgw[mi, :, ai]))
        if s.mx:
            assert lin.jxg is not None and lin.jxf is not None
            assert lin.wx is not None and lin.ex is not None
            jxw = lin.jxg * lin.wx[:, :, None]
            hgg += np.einsum("xka,xkc->ac", jxw, lin.jxg)
            gg += np.einsum("xka,xk->a", jxw, lin.ex)
            xf = s.x_frame >= 0
            np.add.at(hfg, s.x_frame[xf], np.einsum("xkb,xka->xba", lin.jxf[xf], jxw[xf]))
        if lin.wg is not None:
            hgg[np.arange(ng), np.arange(ng)] += lin.wg
            gg += lin.wg * lin.eg
        self.hgg, self.gg, self.hfg, self.hpg = hgg, gg, hfg, hpg

    def _eliminate_globals(self) -> None:
        """Y = N0^-1 N0g and the Cholesky factor of C = Ngg - N0g^T Y."""
        s = self.system
        self.yf, self.yp = self._solve0(self.hfg, self.hpg)
        c = self.hgg - _inner(self.hfg, self.yf) - _inner(self.hpg, self.yp)
        c = 0.5 * (c + c.T)
        try:
            self.c_chol = cho_factor(c, lower=True)
        except np.linalg.LinAlgError:
            d = np.diag(c)
            worst = int(np.argmin(d / np.maximum(np.diag(self.hgg), 1e-300)))
            raise GeometryError(
                f"{s.global_names[worst]} is not determined by the observations (it cannot "
                "be told apart from the orientations, the points or other parameters: hold "
                "it fixed or strengthen the network)") from None
        if not np.all(np.diag(self.c_chol[0]) > 1e-12 * np.sqrt(np.maximum(np.diag(
                self.hgg), 1e-300))):
            worst = int(np.argmin(np.diag(self.c_chol[0])))
            raise GeometryError(
                f"{s.global_names[worst]} is not determined by the observations (it cannot "
                "be told apart from the orientations, the points or other parameters: hold "
                "it fixed or strengthen the network)")

    def _solve0(self, gf: np.ndarray, gp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """N0^-1 [gf; gp] for q columns (the globals held)."""
        s = self.system
        q = gf.shape[2]
        red = self._reduce_rhs(gf, gp)
        xf = self.chol.solve(red.reshape(s.nf * s.b, q)).reshape(s.nf, s.b, q)
        xp = kernels.back_substitute(s.ptr, s.frame_sorted, self.hfp, self.hpp_inv,
                                     np.ascontiguousarray(gp), np.ascontiguousarray(xf))
        return xf, xp

    def _global_part(self, gg: np.ndarray, xf0: np.ndarray, xp0: np.ndarray):
        """xg = C^-1 (gg - N0g^T x0) and the corrected (xf, xp) for q columns."""
        r = gg - _inner(self.hfg, xf0) - _inner(self.hpg, xp0)
        xg = cho_solve(self.c_chol, r)
        return xf0 - self.yf @ xg, xp0 - self.yp @ xg, xg

    @property
    def has_border(self) -> bool:
        return bool(self.system.ng or self.system.mx)

    @single_threaded_blas
    def step(self) -> tuple[np.ndarray, ...]:
        """Corrections to the frame (nf, b) and point (np, d) unknowns (and the global ones,
        (ng,), when the system has any)."""
        s = self.system
        xf = self.chol.solve(self.gf.reshape(-1)).reshape(s.nf, s.b)
        xp = kernels.back_substitute(s.ptr, s.frame_sorted, self.hfp, self.hpp_inv,
                                     self.gp[:, :, None], xf[:, :, None])
        if not s.ng:
            return xf, xp[:, :, 0]
        xf, xp, xg = self._global_part(self.gg[:, None], xf[:, :, None], xp)
        return xf[:, :, 0], xp[:, :, 0], xg[:, 0]

    # ------------------------------------------------------------ covariances
    @single_threaded_blas
    def covariances(self):
        """Selected inverse of N0 (the globals held): Sigma_ff (pattern storage), its
        diagonal blocks, Sigma_pf per observation, Sigma_pp."""
        if self._sel is None:
            s = self.system
            sel = self.chol.selected_inverse()
            values = sel.pattern_values()
            spf, spp = kernels.point_covariances(s.ptr, s.frame_sorted, self.hfp,
                                                 self.hpp_inv, values, s.pair_slot, s.pair_tr,
                                                 s.order)
            self._sel = (sel, values[s.diag_slot], spf, spp)
        return self._sel

    def _c_inv(self) -> np.ndarray:
        return cho_solve(self.c_chol, np.eye(self.system.ng))

    def frame_covariance(self) -> np.ndarray:
        """(nf, b, b) cofactor blocks of the frame unknowns."""
        q = self.covariances()[1]
        if self.system.ng:
            q = q + np.einsum("fbg,gh,fch->fbc", self.yf, self._c_inv(), self.yf)
        return q

    def point_covariance(self) -> np.ndarray:
        """(np, d, d) cofactor blocks of the point unknowns (marginal, not conditional)."""
        q = self.covariances()[3]
        if self.system.ng:
            q = q + np.einsum("pdg,gh,peh->pde", self.yp, self._c_inv(), self.yp)
        return q

    def global_covariance(self) -> np.ndarray:
        """(ng, ng) cofactor matrix of the global unknowns."""
        return self._c_inv()

    def frame_global_covariance(self) -> np.ndarray:
        """(nf, b, ng) cofactors between frame and global unknowns."""
        return -np.einsum("fbg,gh->fbh", self.yf, self._c_inv())

    def _border_rows(self):
        """a = A0 Y - Ag for the three row sets: (m, k, ng), (mp, kp, ng), (mx, kx, ng)."""
        s, lin = self.system, self.lin
        a = (np.einsum("mkb,mbg->mkg", lin.jf, self.yf[s.frame])
             + np.einsum("mkd,mdg->mkg", lin.jp, self.yp[s.point]))
        if lin.jg is not None and s.gcol.shape[1]:
            mi, ai = np.nonzero(s.gcol >= 0)
            np.subtract.at(a, (mi, slice(None), s.gcol[mi, ai]), lin.jg[mi, :, ai])
        ac = np.einsum("mkd,mdg->mkg", lin.jc, self.yp[s.control_point])
        ax = -lin.jxg if s.mx else np.zeros((0, 0, s.ng))
        if s.mx:
            xf = s.x_frame >= 0
            ax = ax.copy()
            ax[xf] += np.einsum("xkb,xbg->xkg", lin.jxf[xf], self.yf[s.x_frame[xf]])
        return a, ac, ax

    def adjusted_cofactors(self) -> tuple[np.ndarray, ...]:
        """Cofactor blocks of the adjusted observations: (m, k, k) and (mp, kp, kp) (and
        (mx, kx, kx) for the extra observations when the system has a border)."""
        lin, system = self.lin, self.system
        _, sff, spf, spp = self.covariances()
        jf, jp = lin.jf, lin.jp
        if jf.size * system.b < ROW_BY_ROW:
            sf = sff[system.frame]
            q = (jf @ sf @ np.swapaxes(jf, 1, 2)
                 + jp @ spp[system.point] @ np.swapaxes(jp, 1, 2))
            cross = jp @ spf @ np.swapaxes(jf, 1, 2)
            q += cross + np.swapaxes(cross, 1, 2)
        else:  # no copy of a frame block per observation (540 MB at 1,000 BAL cameras)
            q = kernels.observation_cofactors(system.frame, system.point,
                                              np.ascontiguousarray(jf, dtype=float),
                                              np.ascontiguousarray(jp, dtype=float), sff,
                                              spf, spp)
        qc = lin.jc @ spp[system.control_point] @ np.swapaxes(lin.jc, 1, 2)
        if not self.has_border:
            return q, qc
        kx = lin.jxg.shape[1] if system.mx and lin.jxg is not None else 0
        qx = np.zeros((system.mx, kx, kx))
        if system.mx:
            xf = system.x_frame >= 0
            assert lin.jxf is not None
            jx = lin.jxf[xf]
            qx[xf] = jx @ sff[system.x_frame[xf]] @ np.swapaxes(jx, 1, 2)
        if system.ng:
            cinv = self._c_inv()
            for rows, out in zip(self._border_rows(), (q, qc, qx), strict=True):
                out += np.einsum("mkg,gh,mlh->mkl", rows, cinv, rows)
        return q, qc, qx

    def extra_cofactor_blocks(self, groups: np.ndarray) -> np.ndarray:
        """(G, k, k) cofactor blocks of the adjusted extra observations in `groups` (G, k)
        of extra-row indices, the rows of a group on one frame (or none), one component
        each (a GNSS position: X, Y, Z of one photo)."""
        lin, s = self.lin, self.system
        groups = np.asarray(groups, np.int64)
        k = groups.shape[1] if groups.ndim == 2 else 0
        out = np.zeros((len(groups), k, k))
        if not len(groups):
            return out
        _, sff, _, _ = self.covariances()
        f = s.x_frame[groups[:, 0]]
        assert lin.jxf is not None
        j = lin.jxf[groups][:, :, 0, :]  # (G, k, b)
        on = f >= 0
        out[on] = j[on] @ sff[f[on]] @ np.swapaxes(j[on], 1, 2)
        if s.ng:
            ax = self._border_rows()[2][:, 0, :]  # (mx, ng)
            a = ax[groups]
            out += np.einsum("Gkg,gh,Glh->Gkl", a, self._c_inv(), a)
        return out

    def point_effect(self) -> tuple[np.ndarray, ...]:
        """Change of the observed point's unknowns per unit error of each observation row.

        (m, k, d) for frame-point observations and (mp, kp, d) for point observations
        (and (mx, kx, 0) for the extra observations, which have no eliminated point):
        dX = Sigma_{X, x} a_i^T p_i, the column of N^-1 A^T P for that row, restricted to
        the point that the observation belongs to.
        """
        lin, system = self.lin, self.system
        _, _, spf, spp = self.covariances()
        g = (spf @ np.swapaxes(lin.jf, 1, 2) + spp[system.point] @ np.swapaxes(lin.jp, 1, 2))
        g = np.swapaxes(g, 1, 2) * lin.w[:, :, None]
        gc = np.swapaxes(spp[system.control_point] @ np.swapaxes(lin.jc, 1, 2), 1, 2)
        gc = gc * lin.wc[:, :, None]
        if not self.has_border:
            return g, gc
        if system.ng:
            cinv = self._c_inv()
            a, ac, _ = self._border_rows()
            g += np.einsum("mdg,gh,mkh->mkd", self.yp[system.point], cinv, a) * \
                lin.w[:, :, None]
            gc += np.einsum("mdg,gh,mkh->mkd", self.yp[system.control_point], cinv, ac) * \
                lin.wc[:, :, None]
        kx = lin.jxg.shape[1] if system.mx and lin.jxg is not None else 0
        return g, gc, np.zeros((system.mx, kx, system.d))

    # ---------------------------------------------------- general columns (H)
    def apply_AtP(self, h: np.ndarray, hc: np.ndarray, hx: np.ndarray | None = None):
        """A^T P [h; hc; hx] for q columns: h (m, k, q), hc (mp, kp, q), hx (mx, kx, q) ->
        (nf, b, q), (np, d, q) (and (ng, q) when the system has a border)."""
        lin, s = self.lin, self.system
        q = h.shape[2]
        gf = np.zeros((s.nf, s.b, q))
        gp = np.zeros((s.np, s.d, q))
        hw = h * lin.w[:, :, None]
        np.add.at(gf, s.frame, np.einsum("mkb,mkq->mbq", lin.jf, hw))
        np.add.at(gp, s.point, np.einsum("mkd,mkq->mdq", lin.jp, hw))
        np.add.at(gp, s.control_point,
                  np.einsum("mkd,mkq->mdq", lin.jc, hc * lin.wc[:, :, None]))
        if not self.has_border:
            return gf, gp
        gg = np.zeros((s.ng, q))
        if lin.jg is not None and s.gcol.shape[1]:
            mi, ai = np.nonzero(s.gcol >= 0)
            np.add.at(gg, s.gcol[mi, ai], np.einsum("mk,mkq->mq", lin.jg[mi, :, ai], hw[mi]))
        if s.mx:
            assert hx is not None and lin.wx is not None
            assert lin.jxg is not None and lin.jxf is not None
            hxw = hx * lin.wx[:, :, None]
            gg += np.einsum("xkg,xkq->gq", lin.jxg, hxw)
            xf = s.x_frame >= 0
            np.add.at(gf, s.x_frame[xf], np.einsum("xkb,xkq->xbq", lin.jxf[xf], hxw[xf]))
        return gf, gp, gg

    def _reduce_rhs(self, gf: np.ndarray, gp: np.ndarray) -> np.ndarray:
        """gf - sum Hfp Hpp^-1 gp for q columns, (nf, b, q)."""
        s = self.system
        red = np.array(gf, dtype=float, order="C")
        kernels.reduce_rhs_columns(s.ptr, s.frame_sorted, self.hfp, self.hpp_inv,
                                   np.ascontiguousarray(gp, dtype=float), red)
        return red

    @single_threaded_blas
    def solve_normal(self, gf: np.ndarray, gp: np.ndarray, gg: np.ndarray | None = None):
        """N^-1 [gf; gp; gg] for q columns (gg only when the system has a border)."""
        xf, xp = self._solve0(gf, gp)
        if not self.has_border:
            return xf, xp
        if not self.system.ng:
            return xf, xp, np.zeros((0, gf.shape[2]))
        assert gg is not None  # a border with global unknowns
        return self._global_part(gg, xf, xp)

    @single_threaded_blas
    def forward(self, gf: np.ndarray, gp: np.ndarray, gg: np.ndarray | None = None
                ) -> np.ndarray:
        """W with W^T W = g^T N^-1 g for q columns (FOTEF: one forward substitution)."""
        s = self.system
        q = gf.shape[2]
        red = self._reduce_rhs(gf, gp)
        wf = self.chol.forward(red.reshape(s.nf * s.b, q))
        # Hpp = L L^T per point: the point part of the forward substitution is L^-1 gp
        wp = np.linalg.solve(self.hpp_l, gp)
        out = np.concatenate([wp.reshape(s.np * s.d, q), wf.reshape(-1, q)])
        if not s.ng:
            return out
        xf0, xp0 = self._solve0(gf, gp)
        r = gg - _inner(self.hfg, xf0) - _inner(self.hpg, xp0)
        wg = solve_triangular(self.c_chol[0], r, lower=True)
        return np.concatenate([out, wg])

    def apply_A(self, xf: np.ndarray, xp: np.ndarray, xg: np.ndarray | None = None):
        """A x for q columns: (m, k, q), (mp, kp, q) (and (mx, kx, q) with a border)."""
        lin, s = self.lin, self.system
        rows = (np.einsum("mkb,mbq->mkq", lin.jf, xf[s.frame])
                + np.einsum("mkd,mdq->mkq", lin.jp, xp[s.point]))
        rows_c = np.einsum("mkd,mdq->mkq", lin.jc, xp[s.control_point])
        if not self.has_border:
            return rows, rows_c
        q = xf.shape[2]
        if lin.jg is not None and s.gcol.shape[1] and s.ng:
            mi, ai = np.nonzero(s.gcol >= 0)
            assert xg is not None
            np.add.at(rows, mi, np.einsum("mk,mq->mkq", lin.jg[mi, :, ai], xg[s.gcol[mi, ai]]))
        kx = lin.jxg.shape[1] if s.mx and lin.jxg is not None else 0
        rows_x = np.zeros((s.mx, kx, q))
        if s.mx:
            assert xg is not None and lin.jxg is not None and lin.jxf is not None
            rows_x += np.einsum("xkg,gq->xkq", lin.jxg, xg)
            xfm = s.x_frame >= 0
            rows_x[xfm] += np.einsum("xkb,xbq->xkq", lin.jxf[xfm], xf[s.x_frame[xfm]])
        return rows, rows_c, rows_x


NULL = 1e-7  # an eigenvalue of a diagonal block scaled to unit diagonal below this: singular


def dependent_columns(block: np.ndarray) -> tuple[list[int], int]:
    """(the columns of a symmetric block (lower triangle given) that its null space moves,
    its dimension): the eigenvectors of the eigenvalues below NULL of the block scaled to
    unit diagonal, the columns whose share in them is at least 0.2 of the largest, in
    column order; a column without any weight alone.  ([], 0) when the block is regular."""
    a = np.tril(block) + np.tril(block, -1).T
    d = np.diag(a).copy()
    empty = np.flatnonzero(~(d > 0))
    if len(empty):
        return [int(empty[0])], 1
    sc = 1.0 / np.sqrt(d)
    lam, vec = np.linalg.eigh(sc[:, None] * a * sc[None, :])
    null = vec[:, lam < NULL]
    if not null.shape[1]:
        return [], 0
    share = np.linalg.norm(null, axis=1)
    return [int(i) for i in np.flatnonzero(share >= 0.2 * share.max())], null.shape[1]
