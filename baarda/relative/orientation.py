"""Relative orientation of one model with optional scale transfer (Kratky and El-Hakim 1983).

The combined model  A v + B g + u = 0  (eq. 2) has one observation per condition: y'' in
the coplanarity condition of every point, x'' in the collinearity condition of every tie
point (parallax mode: the left coordinates are fixed).  A is diagonal, so the parametric form
with pseudo-observations l = -u and pseudo-weights P = (A Q A^T)^-1 (eq. 3-4) is, after
dividing each condition by its a_i, a parametric model in the observations themselves:

    v_i(g) = -F_i(g) / a_i(g)          (exact: F is linear in the right image coordinates)

with weights 1/sigma_i^2, sigma_x for x'' and sqrt(q_yy/q_xx) sigma_x for y'' (Kratky:
q_yy = 2 q_xx), solved by the one solver (adjustment/solve.py); the Jacobian dv/dg is the
design matrix handed to the quality layer (baarda.quality.dense_model.DenseModel), residuals
and sigmas in µm.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from baarda.adjustment.dense import DenseLeastSquares
from baarda.adjustment.solve import solve
from baarda.block.rotation import angles_from_matrix
from baarda.errors import GeometryError
from baarda.options import DEFAULT_QTIE, DEFAULT_QYY, SolveOptions
from baarda.quality.dense_model import DenseModel
from baarda.relative.coplanarity import coplanarity, image_vectors, right_rotation
from baarda.relative.scale_transfer import collinearity_xz
from baarda.sections import Section, section

# the variance-component groups: y'' of every point, x'' of the tie points
VARIANCE_GROUPS = {"y": "parallax y (coplanarity)", "x": "parallax x (scale transfer)"}
PARAMETER_NAMES = ("beta_x", "beta_y", "beta_z", "kappa", "phi", "omega")
# converged when max |dg| < 1e-12 (rad, base units); at the iteration limit or when no step
# lowers v'Pv any more, converged if max |dg| <= 1e-9 (the rounding floor)
SOLVE = SolveOptions(max_iterations=30, tolerance=1e-12, stall_tolerance=1e-9, min_step=1e-6,
                     final_step=True)


@dataclass
class PhotoPose:
    """A photo in the strip frame: projection centre (3,) in model units, rotation (3, 3)."""

    centre: np.ndarray
    rotation: np.ndarray


@dataclass
class ModelSetup:
    """Everything of one model but its measurements.

    c: principal distance (mm); left: pose of the left photo (fixed); base_ref: the base b_x of
    the first model or of the preceding one (model units); tie_index: indices of the tie points
    among the model's points, tie_xyz (m, 3): their strip coordinates from the preceding model;
    scale: solve beta_x (6 unknowns) or keep b_x = base_ref (5 unknowns, first model);
    sigma_x: a-priori sigma of x'' in µm; qyy: q_yy / q_xx (Kratky: 2); qtie: the cofactor of x''
    in the tie condition / q_xx (Kratky: 1; the tie coordinates are taken as errorless).
    """

    c: float
    left: PhotoPose
    base_ref: float
    tie_index: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    tie_xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    scale: bool = False
    sigma_x: float = 10.0
    qyy: float = DEFAULT_QYY
    qtie: float = DEFAULT_QTIE

    @property
    def unknowns(self) -> np.ndarray:
        """Indices of the solved parameters in (beta_x, beta_y, beta_z, kappa, phi, omega)."""
        return np.arange(6) if self.scale else np.arange(1, 6)


def parallax_sigma(component: np.ndarray, sigma_x: float, qyy: float,
                   qtie: float) -> np.ndarray:
    """The a-priori sigma (µm) of each observation: sqrt(q_yy / q_xx) sigma_x for a y''
    (component "y"), sqrt(q_tie) sigma_x for the x'' of a tie point ("x")."""
    return np.where(np.asarray(component) == "y", np.sqrt(qyy), np.sqrt(qtie)) * sigma_x  # type: ignore[operator]  # numpy stubs


def residual_function(g: np.ndarray, setup: ModelSetup, left_xy: np.ndarray,
                      right_xy: np.ndarray, delta: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Residuals v (n + m,) in µm (y'' of all points, then x'' of tie points) and dv/dg (., 6).

    delta (n + m,) µm: errors added to the observations as the model sees them (A diagonal:
    an error in y'' enters the coplanarity condition only, one in x'' the collinearity only).
    """
    x_left = image_vectors(left_xy, setup.c) @ setup.left.rotation.T
    u_right = image_vectors(right_xy, setup.c)
    rot, parts = right_rotation(g[3:6])
    conds = [coplanarity(g[:3], x_left, u_right, rot, parts)]
    ti = setup.tie_index
    if len(ti):
        conds.append(collinearity_xz(g[:3], setup.base_ref, setup.left.centre, setup.tie_xyz,
                                     u_right[ti], rot, parts))
    f = np.concatenate([c.f for c in conds])
    a = np.concatenate([c.a for c in conds])
    df = np.concatenate([c.df_dg for c in conds])
    da = np.concatenate([c.da_dg for c in conds])
    if np.any(np.abs(a) < 1e-9 * setup.c**2):
        raise GeometryError("a condition does not depend on its observation (degenerate ray)")
    v = -f / a * 1000.0
    if delta is not None:
        v = v - delta
    jac = -(df * a[:, None] - f[:, None] * da) / a[:, None] ** 2 * 1000.0
    return v, jac


def intersect(c1: np.ndarray, d1: np.ndarray, c2: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Midpoints of the shortest segments between rays c1 + s d1 and c2 + t d2 (n, 3)."""
    w = c1 - c2
    a = np.einsum("ij,ij->i", d1, d1)
    b = np.einsum("ij,ij->i", d1, d2)
    cc = np.einsum("ij,ij->i", d2, d2)
    d = np.einsum("ij,ij->i", d1, w)
    e = np.einsum("ij,ij->i", d2, w)
    den = a * cc - b * b
    s = (b * e - cc * d) / den
    t = (a * e - b * d) / den
    return 0.5 * ((c1 + s[:, None] * d1) + (c2 + t[:, None] * d2))


@dataclass
class Orientation:
    """The adjusted model.  Residuals v = adjusted - observed in µm."""

    name: str
    points: list[str]
    setup: ModelSetup
    params: np.ndarray  # (6,) beta_x, beta_y, beta_z, kappa, phi, omega
    right: PhotoPose
    base: float  # b_x in model units
    residuals: np.ndarray  # (n + m,) µm
    sigma: np.ndarray  # (n + m,) µm
    design: np.ndarray  # (n + m, u) dv/dg in µm per unit of the solved parameters
    obs_point: np.ndarray  # (n + m,) index of the point
    obs_component: np.ndarray  # (n + m,) "y" or "x"
    model_xyz: np.ndarray  # (n, 3) intersected model coordinates, model units
    tie_discrepancy: np.ndarray  # (m, 3) new - preceding coordinates, µm (model mm)
    iterations: int

    @property
    def y_parallax(self) -> np.ndarray:
        """y-parallax of every point after orientation, µm: observed - adjusted y'' (= -v)."""
        return -self.residuals[: len(self.points)]

    @property
    def x_parallax(self) -> np.ndarray:
        """x'' discrepancy of every tie point after orientation, µm (= -v)."""
        return -self.residuals[len(self.points):]

    def labels(self) -> list[str]:
        return [f"{self.points[i]} {c}" for i, c in zip(self.obs_point, self.obs_component,
                                                        strict=True)]

    def to_dict(self) -> dict:
        """The orientation's figures (summary.json style)."""
        n, u = self.design.shape
        vtpv = float(np.sum((self.residuals / self.sigma) ** 2))
        return {"model": self.name, "n_observations": n, "n_unknowns": u, "redundancy": n - u,
                "vtpv": vtpv, "sigma0": float(np.sqrt(vtpv / (n - u))) if n > u else None,
                "iterations": self.iterations, "converged": True, "base": self.base,
                "parameters": {PARAMETER_NAMES[k]: float(self.params[k])
                               for k in self.setup.unknowns}, "notes": []}

    def sections(self) -> list[Section]:
        d = self.to_dict()
        kind = "with scale transfer" if self.setup.scale else "first model"
        params = ", ".join(f"{k} {v:.6g}" for k, v in d["parameters"].items())
        return [section(f"Relative orientation, model {self.name} ({kind})", [
            f"{len(self.points)} points, {len(self.setup.tie_index)} tie points: observations "
            f"{d['n_observations']}, unknowns {d['n_unknowns']}, redundancy {d['redundancy']}",
            f"iterations {d['iterations']}; b_x {self.base:.6g}; {params} (rad)"])]

    def dense_model(self, sigma: np.ndarray | None = None) -> DenseModel:
        """The parametric form as the quality layer's DenseModel (µm); its variance groups
        are the y'' of the coplanarity conditions and the x'' of the scale transfer.
        `sigma`: other a-priori sigmas (the residuals stay those of this orientation)."""
        n = len(self.residuals)
        model = DenseModel(self.design, self.sigma if sigma is None else sigma,
                           self.residuals, kind=["parallax"] * n,
                           component=list(self.obs_component), frame=[self.name] * n,
                           point=[self.points[i] for i in self.obs_point],
                           variance_group=[VARIANCE_GROUPS[c] for c in self.obs_component])
        model.units, model.frame_kind = {"parallax": (1.0, "µm")}, "model"
        return model


def orient(name: str, points: list[str], left_xy: np.ndarray, right_xy: np.ndarray,
           setup: ModelSetup, g0: np.ndarray | None = None, max_iter: int = 30,
           tol: float = 1e-12, delta: np.ndarray | None = None) -> Orientation:
    """Orient one model from g0 (default: the left photo's attitude).

    left_xy, right_xy (n, 2): image coordinates in mm of the model's points; delta: see
    residual_function.
    """
    left_xy = np.asarray(left_xy, float)
    right_xy = np.asarray(right_xy, float)
    n, m = len(points), len(setup.tie_index)
    unk = setup.unknowns
    if setup.scale and m == 0:
        raise GeometryError(f"model {name}: the scale transfer needs at least one tie point")
    if n + m < len(unk) + 1:
        raise GeometryError(f"model {name}: {n} points and {m} tie points give no redundancy "
                            f"for {len(unk)} unknowns (need at least {len(unk) + 1} "
                            "observations)")
    if g0 is None:
        g0 = np.concatenate([[1.0, 0.0, 0.0], angles_from_matrix(setup.left.rotation)[::-1]])
    g = np.asarray(g0, float).copy()
    comp = np.array(["y"] * n + ["x"] * m, dtype=object)
    sig = parallax_sigma(comp, setup.sigma_x, setup.qyy, setup.qtie)

    def residuals(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        gx = g.copy()
        gx[unk] = x
        v, jac = residual_function(gx, setup, left_xy, right_xy, delta)
        return v, jac[:, unk]  # observed = 0: the misclosure is -v

    problem = DenseLeastSquares(residuals, np.zeros(n + m), 1.0 / sig**2, max_condition=1e12,
                                correction=lambda x, dx: float(np.max(np.abs(dx))),
                                what=f"model {name}: the orientation")
    options = replace(SOLVE, max_iterations=max_iter, tolerance=tol)
    sol = solve(problem, g[unk].copy(), options)
    if not sol.converged:
        raise GeometryError(f"model {name}: orientation did not converge in {max_iter} "
                            "iterations")
    g[unk] = sol.state
    it = sol.iterations
    v, jac = residual_function(g, setup, left_xy, right_xy, delta)
    rot, _ = right_rotation(g[3:6])
    bx = g[0] * setup.base_ref
    right = PhotoPose(setup.left.centre + bx * np.array([1.0, g[1], g[2]]), rot)
    d1 = image_vectors(left_xy, setup.c) @ setup.left.rotation.T
    d2 = image_vectors(right_xy, setup.c) @ rot.T
    xyz = intersect(np.broadcast_to(setup.left.centre, d1.shape), d1,
                    np.broadcast_to(right.centre, d2.shape), d2)
    disc = (xyz[setup.tie_index] - setup.tie_xyz) * 1000.0
    obs_point = np.concatenate([np.arange(n), setup.tie_index]).astype(int)
    return Orientation(name, list(points), setup, g, right, bx, v, sig, jac[:, unk], obs_point,
                       comp, xyz, disc, it)
