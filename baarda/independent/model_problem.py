"""An independent-model block in the form of the generic point-eliminated adjustment.

Frames are models, points are terrain points; three kinds of adjustment share the code:

=======  ===========================================  ===  ===  =========================
mode     observation equation of a model row          b    d    components
=======  ===========================================  ===  ===  =========================
3d       x = c + mu R^T (X - T)    (similarity.py)    7    3    x, y, z
2d       (x, y) = c + mu R(k)^T (X - T)               4    2    x, y   (no proj. centres)
height   z = c_z + mu_m (Z - Z_ref) + a0 + a1 u + a2 v  3  1    z      (mu_m from 2d)
=======  ===========================================  ===  ===  =========================

(u, v: model coordinates about the centroid / model radius L, so a1, a2 are the height
changes in mm at the model's edge.)  Control coordinates are point observations.  Terrain
coordinates are reduced by `origin` inside.  With a full covariance per row (obs_cov) each
row is decorrelated by G = D L^-1 (C = L L^T, D = diag L): the first component stays, the
others become their part not predicted by the previous ones (x, y|x, z|xy), with
standard deviations diag(L); weights stay diagonal.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from baarda.adjustment.schur_model import FlatLayout
from baarda.adjustment.schur_problem import SchurProblem
from baarda.adjustment.schur_system import HOLD, Linearization, SchurSystem
from baarda.adjustment.solve import solve_continued, solve_notes
from baarda.block.model_block import ModelBlock
from baarda.block.model_deformations import model_radius
from baarda.errors import GeometryError
from baarda.independent import similarity
from baarda.options import SolveOptions

if TYPE_CHECKING:
    from baarda.independent.model_result import ModelResult

MODES = {"3d": (7, 3, (0, 1, 2)), "2d": (4, 2, (0, 1)), "height": (3, 1, (2,))}
COMPONENTS = {"3d": ("x", "y", "z"), "2d": ("x", "y"), "height": ("z",)}
CORRELATED = {"3d": ("x", "y|x", "z|xy"), "2d": ("x", "y|x"), "height": ("z",)}
XYZ = np.array(["X", "Y", "Z"], dtype=object)
# converged when the correction is below 1e-9 of the model radius in the terrain and 1e-11
# rad and relative scale (correction_size weighs those by 100), or when v'Pv stops
# changing (1e-12) with corrections below 1e-7 of that radius and 1e-9; that last
# correction is applied (final_step)
SOLVE = SolveOptions(max_iterations=50, tolerance=1e-9, flat_cost=1e-12, flat_tolerance=1e-7,
                     min_step=1e-3, final_step=True)


class ModelProblem(SchurProblem):
    """Index arrays, weights and the Schur structure of one adjustment of a model block.

    Observation vector (flat, the quality layer's): the k components of every model row of
    the adjustment (mm; decorrelated when a full covariance is given), then every observed
    control component (m).  `obs_keep` (m, 3) and `control_keep` (np, 3) give the
    components that start switched off (the pre-adjustment's findings); `mu` (nm,) is
    required for mode 'height'.  The problem never changes: `reweighted(active, factors)`
    is a new one with other components switched off or re-weighted.
    """

    def __init__(self, block: ModelBlock, mode: str = "3d", *, obs_keep=None,
                 control_keep=None, mu: np.ndarray | None = None, include_pc: bool | None = None,
                 origin: np.ndarray | None = None):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}")
        self.block, self.mode = block, mode
        self.b, self.d, comps = MODES[mode]
        self.comps = np.asarray(comps)
        self.k = len(comps)
        bl = block
        pc_rows = bl.pc[bl.obs_point]
        if include_pc is None:
            include_pc = mode != "2d"
        use = np.ones(len(bl.obs_model), bool) if include_pc else ~pc_rows
        finite = np.isfinite(bl.obs_xyz[:, self.comps]).all(axis=1)
        if mode == "3d" and not finite[use].all():
            raise GeometryError("the 3D adjustment needs z of every model point (models.csv "
                                "has empty z_mm); use the planimetric adjustment (--2d)")
        self.rows = np.flatnonzero(use & finite)
        self.point_ids = np.unique(bl.obs_point[self.rows])  # block index of each point
        remap = np.full(bl.n_points, -1)
        remap[self.point_ids] = np.arange(len(self.point_ids))
        self.remap = remap
        ctrl = bl.controlled[:, self.comps].any(axis=1) & (remap >= 0)
        self.control = np.flatnonzero(ctrl)
        sig = bl.sigma[self.control][:, self.comps]
        given = np.isfinite(sig) & (bl.role[self.control] == "control")[:, None]
        ok = given & (sig > 0)
        self.held = np.zeros((len(self.point_ids), self.d), bool)  # fixed control (sigma 0)
        self.held[remap[self.control]] = given & (sig == 0)
        self.wc_full = np.where(ok, 1.0 / np.where(ok, sig, 1.0) ** 2, 0.0)
        self.frame = bl.obs_model[self.rows]
        self.centroid = bl.centroids()
        self.radius = model_radius(bl, self.centroid)
        self.obs = bl.obs_xyz[self.rows][:, self.comps]
        # weights, with the per-row decorrelation G = D L^-1 when a covariance is given
        self.transform = None
        if bl.obs_cov is not None and self.k > 1:
            cov = bl.obs_cov[self.rows][:, self.comps][:, :, self.comps]
            lo = np.linalg.cholesky(cov)
            dg = np.diagonal(lo, axis1=1, axis2=2)
            self.transform = dg[:, :, None] * np.linalg.inv(lo)
            self.sigma_obs = dg.copy()
        else:
            self.sigma_obs = bl.obs_sigma[self.rows][:, self.comps]
        m, nc = len(self.rows), len(self.control)
        self.layout = FlatLayout(m, self.k, nc, self.k, np.flatnonzero(self.wc_full.ravel() > 0))
        sel = self.layout.ctrl_sel
        sig_c = 1.0 / np.sqrt(np.where(self.wc_full > 0, self.wc_full, 1.0))
        self.sigma_apriori = np.concatenate([self.sigma_obs.ravel(), sig_c.ravel()[sel]])
        self._labels(m, sel)
        if mode == "height":
            if mu is None:
                raise ValueError("the height adjustment needs the scale mu of each model")
            self.mu = np.asarray(mu, float)
        given = bl.xyz[self.control]
        if origin is None:
            pts = given if np.isfinite(given).any() else np.zeros((1, 3))
            origin = np.array([np.nanmean(pts[:, c]) if np.isfinite(pts[:, c]).any() else 0.0
                               for c in range(3)])
        self.origin = np.asarray(origin, float)
        self.system = SchurSystem(
            bl.n_models, self.b, len(self.point_ids), self.d, self.frame,
            remap[bl.obs_point[self.rows]], remap[self.control],
            frame_names=[f"model {m}" for m in bl.models],
            point_names=[bl.points[j] for j in self.point_ids], n_fixed=int(self.held.sum()))
        keep = np.ones((len(bl.obs_model), 3), bool) if obs_keep is None else \
            np.asarray(obs_keep, bool)
        ckeep = np.ones((bl.n_points, 3), bool) if control_keep is None else \
            np.asarray(control_keep, bool)
        active = self.layout.flat(keep[self.rows][:, self.comps],
                                  ckeep[self.control][:, self.comps])
        self._set_weights(active, np.ones(self.layout.n))
        self.check_datum()

    def _labels(self, m: int, sel: np.ndarray) -> None:
        bl, k = self.block, self.k
        nc = len(sel)
        models = np.asarray(bl.models, dtype=object)
        pids = np.asarray(bl.points, dtype=object)
        names = CORRELATED[self.mode] if self.transform is not None else COMPONENTS[self.mode]
        self.kind = np.array(["model"] * (m * k) + ["control"] * nc, dtype=object)
        self.component = np.concatenate([np.tile(np.array(names, dtype=object), m),
                                         np.tile(XYZ[self.comps], len(self.control))[sel]])
        self.frame_label = np.concatenate([np.repeat(models[self.frame], k),
                                           np.full(nc, "", dtype=object)])
        self.point_label = np.concatenate([np.repeat(pids[bl.obs_point[self.rows]], k),
                                           np.repeat(pids[self.control], k)[sel]])
        self.group = np.concatenate([np.repeat(np.arange(m), k), np.full(nc, -1)])
        # back into the block tables: model row (or -1), control point (or -1), xyz column
        self.block_row = np.concatenate([np.repeat(self.rows, k), np.full(nc, -1)])
        self.block_point = np.concatenate([np.full(m * k, -1),
                                           np.repeat(self.control, k)[sel]])
        self.xyz_col = np.concatenate([np.tile(self.comps, m),
                                       np.tile(self.comps, len(self.control))[sel]])

    # ------------------------------------------------------------------ checks
    def check_datum(self) -> None:
        bl = self.block
        keep = (self.wc.reshape(len(self.control), self.k) > 0) | \
            self.held[self.remap[self.control]]
        xyz = bl.xyz[self.control]
        problems = []
        npts = np.bincount(self.frame, minlength=bl.n_models)
        need = {"3d": 3, "2d": 2, "height": 3}[self.mode]
        few = [bl.models[i] for i in np.flatnonzero((npts > 0) & (npts < need))]
        if few:
            problems.append(f"model(s) {', '.join(few[:10])} have fewer than {need} points")
        empty = [bl.models[i] for i in np.flatnonzero(npts == 0)]
        if empty:
            problems.append(f"model(s) {', '.join(empty[:10])} have no usable points")
        if self.mode in ("3d", "2d"):
            plan = np.flatnonzero(keep[:, 0] & keep[:, 1])
            if len(plan) < 2 or np.ptp(xyz[plan, :2], axis=0).max(initial=0) <= 0:
                problems.append(f"{len(plan)} distinct planimetric (X, Y) control point(s); at "
                                "least two are needed for position, scale and azimuth")
        if self.mode in ("3d", "height"):
            hz = np.flatnonzero(keep[:, -1])
            known = hz[np.isfinite(xyz[hz, :2]).all(axis=1)]  # XY known: check the line
            s = np.ones(2)
            if len(known) == len(hz) and len(hz) >= 3:
                p = xyz[hz, :2] - xyz[hz, :2].mean(axis=0)
                s = np.linalg.svd(p, compute_uv=False)
            if len(hz) < 3 or s[-1] <= 1e-6 * max(s[0], 1e-9):
                problems.append(f"{len(hz)} height control point(s): at least three not on "
                                "one line are needed to fix the tilt of the block")
        if problems:
            raise GeometryError("the model block cannot be adjusted: " + "; ".join(problems))

    # ------------------------------------------------------------------ numbers
    def uv(self) -> np.ndarray:
        """(m, 2) planimetric model coordinates about the centroid / model radius."""
        bl = self.block
        return (bl.obs_xyz[self.rows, :2] - self.centroid[self.frame, :2]) / self.radius

    def predict(self, params: np.ndarray, pts: np.ndarray):
        """Model coordinates f (m, k) of the current unknowns and Jacobians (m,k,b), (m,k,d)."""
        bl = self.block
        p = pts[self.remap[bl.obs_point[self.rows]]]
        par = params[self.frame]
        c = self.centroid[self.frame]
        if self.mode == "3d":
            return similarity.inverse3d(par, p, c)
        if self.mode == "2d":
            return similarity.inverse2d(par, p, c[:, :2])
        uv = self.uv()
        mu = self.mu[self.frame]
        f = c[:, 2] + mu * p[:, 0] + par[:, 0] + par[:, 1] * uv[:, 0] + par[:, 2] * uv[:, 1]
        jf = np.column_stack([np.ones(len(f)), uv])[:, None, :]
        jp = mu[:, None, None] * np.ones((len(f), 1, 1))
        return f[:, None], jf, jp

    def transform_rows(self, h: np.ndarray) -> np.ndarray:
        """Apply the decorrelation G to per-row vectors h (m, k, q) (identity if none)."""
        if self.transform is None:
            return h
        return self.transform @ h

    # ------------------------------------------------- the solver's protocol
    def linearize(self, state: tuple[np.ndarray, np.ndarray]) -> Linearization:
        """Jacobians and misclosures e = l - f at (params, reduced terrain points)."""
        params, pts = state
        f, jf, jp = self.predict(params, pts)
        e = self.obs - f
        if self.transform is not None:
            g = self.transform
            e = np.einsum("mij,mj->mi", g, e)
            jf, jp = g @ jf, g @ jp
        given = self.block.xyz[self.control][:, self.comps] - self.origin[self.comps]
        ec = np.where(np.isfinite(given), given, 0.0) - pts[self.remap[self.control]]
        jc = np.broadcast_to(np.eye(self.d), (len(self.control), self.d, self.d)).copy()
        wp = ep = None
        if self.held.any():  # fixed control: not unknowns (zero columns, held exactly)
            jp = np.where(self.held[self.remap[self.block.obs_point[self.rows]]][:, None, :],
                          0.0, jp)
            wp = np.where(self.held, HOLD, 0.0)
            ep = np.zeros_like(wp)
            ep[self.remap[self.control]] = np.where(self.held[self.remap[self.control]], ec,
                                                    0.0)
        # misclosures of rejected components stay (predicted residuals); weight 0 in N
        return Linearization(jf, jp, self.w, e, jc, self.wc, np.where(self.wc_full > 0, ec, 0.0),
                             wp=wp, ep=ep)

    def _sizes(self, state, step, t: float = 1.0) -> tuple[float, float, float]:
        params = state[0]
        dxf, dxp = step
        dpos = np.max(np.abs(dxp), initial=0.0)
        if self.mode == "3d":
            dpos = max(dpos, np.max(np.abs(dxf[:, :3]), initial=0.0))
            dang = np.max(np.abs(dxf[:, 3:6]), initial=0.0)
            dmu = np.max(np.abs(dxf[:, 6] / params[:, 6]), initial=0.0)
        elif self.mode == "2d":
            dpos = max(dpos, np.max(np.abs(dxf[:, :2]), initial=0.0))
            dang = np.max(np.abs(dxf[:, 2]), initial=0.0)
            dmu = np.max(np.abs(dxf[:, 3] / params[:, 3]), initial=0.0)
        else:
            dang, dmu = 0.0, np.max(np.abs(dxf), initial=0.0) * 1e-3
        return t * float(dpos), t * float(dang), t * float(dmu)

    def terrain_size(self, params: np.ndarray) -> float:
        """The typical model radius in the terrain [m]: radius (mm) / median scale mu."""
        return self.radius / (float(np.median(params[:, -1])) if self.mode != "height"
                              else 1.0)

    def correction_size(self, state, step) -> float:
        dpos, dang, dmu = self._sizes(state, step)
        return max(dpos / self.terrain_size(state[0]), 100.0 * dang, 100.0 * dmu)

    def describe(self, state, step, t: float) -> str:
        return f"{self._sizes(state, step, t)[0]:.3g} m"

    # ------------------------------------------------------------ fit
    def fit(self, start: tuple[np.ndarray, np.ndarray] | None = None,
            options: SolveOptions = SOLVE, progress=None) -> ModelResult:
        """Adjust; returns a ModelResult.

        `start` = (params (nm, b) with T reduced by origin, points (np_used, d) reduced);
        without it the approximations come from the pre-adjustment connection of the models
        (3d, 2d) or zero (height: the model is linear).
        """
        from baarda.independent.model_result import ModelResult
        from baarda.independent.preadjust import approximations  # uses this module

        t0 = time.perf_counter()
        if start is None:
            if self.mode == "height":
                start = (np.zeros((self.block.n_models, 3)), np.zeros((len(self.point_ids), 1)))
            else:
                start = approximations(self)
        sol, gn = solve_continued(self, tuple(np.array(a, float) for a in start), options,
                                  progress, label=f"{self.mode} ")
        notes = tuple(solve_notes(sol, gn))
        params, pts = sol.state
        return ModelResult(self, params, pts, sol.lin, sol.factor, sol.iterations,
                           sol.converged, notes, time.perf_counter() - t0)


def adjust_models(block: ModelBlock, mode: str = "3d", *,
                  start: tuple[np.ndarray, np.ndarray] | None = None,
                  options: SolveOptions = SOLVE, progress=None, **problem_args) -> ModelResult:
    """Adjust the model block in `mode` (3d, 2d or height); problem_args go to ModelProblem
    (obs_keep, control_keep, mu, include_pc, origin)."""
    return ModelProblem(block, mode, **problem_args).fit(start, options, progress)
