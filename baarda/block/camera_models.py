"""Camera models for self-calibration: corrections and their analytic Jacobians.

Pure, vectorised functions; the bundle does the chain rule with the projection
(docs/camera_models.md has the formulas, units, sources and sign conventions).  Image
coordinates are in mm in baarda's image frame (x right, y up); pp is the principal point, c
the camera constant.  Every model gives a correction delta(u) of a reduced coordinate u:

* backward (photogrammetric): u = observed - pp (mm), ideal = pp + u + delta(u);
* forward: u = ideal - pp (mm), or (ideal - pp) / c for a ``normalized`` model, and
  projected = pp + s (u + delta(u)) with s = c if normalized, else 1.

Models (coefficients in the order of ``params``; units for u in mm):

* ``none``: no coefficients.
* ``brown``: backward, Fraser's form: Brown radial k1..k3 (mm^-2, mm^-4, mm^-6), decentring
  p1, p2 (mm^-1), affinity and shear b1, b2 (dimensionless).
* ``dbat3``, ``dbat5``: backward, DBAT's models 3 (res_euler_brown_1: affine [1+b1, b2; 0, 1]
  after pp, then Brown) and 5 (res_euler_brown_3: x scaled by 1 + b1 before pp, Brown,
  then skew [1, b2; 0, 1]); delta includes the affine part.  `principal_point_from_dbat`
  and `principal_point_to_dbat` map DBAT's pp to baarda's.
* ``brown_forward``: forward, normalised: Brown on n = (ideal - pp)/c, then the aspect a
  multiplies y by 1 + a (OpenCV/COLMAP with y up: their (p1, p2) are baarda's (p2, -p1)).
* ``fisheye_forward``: forward, normalised: the equidistant fisheye theta_d = theta (1 + k1
  theta^2 + ... + k4 theta^8), theta = atan(|n|), then the aspect a (OpenSfM's fisheye and
  fisheye_opencv; with all coefficients 0 it is the equidistant projection, not none).
* ``aicon``: forward, mm: AICON 3D Studio's A1..A3 (zero crossing at the constant r0),
  B1, B2, C1, C2.
* ``ebner``: backward, mm: Ebner's 12 additional parameters on a 3x3 grid of spacing b.
* ``gruen``: backward, mm: 44 fields orthonormal over a 5x5 grid of spacing b that span the
  space of Gruen's 44 parameters (a documented construction, not Gruen's numbering).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from baarda.block.field_models import ebner_terms, gruen_terms

Terms = tuple[np.ndarray, np.ndarray, np.ndarray]
BROWN = ("k1", "k2", "k3", "p1", "p2")


@dataclass(frozen=True)
class CameraModel:
    """A camera model: the correction delta(u) and its derivatives, vectorised over rows."""

    name: str
    side: str  # "backward" or "forward"
    params: tuple[str, ...]
    constants: tuple[str, ...]
    normalized: bool
    description: str
    terms: Callable[[np.ndarray, np.ndarray, np.ndarray], Terms] = field(
        repr=False, compare=False)
    # the groups of its parameters that a self-calibration tests together, (label, names);
    # empty: one group of all of them (named after the model)
    groups: tuple[tuple[str, tuple[str, ...]], ...] = ()

    @property
    def parameter_groups(self) -> tuple[tuple[str, tuple[str, ...]], ...]:
        return self.groups or ((f"{self.name} additional parameters", self.params),)

    @property
    def n_params(self) -> int:
        return len(self.params)

    def correction(self, u: ArrayLike, coef: ArrayLike | None,
                   const: ArrayLike | None = None) -> Terms:
        """delta (m, 2) [mm, or dimensionless if normalized], d delta / d u (m, 2, 2) and
        d delta / d coef (m, 2, k) at u (m, 2) for coefficients coef (m, k) and constants
        const (m, len(constants)); coef and const broadcast (one row for all is fine)."""
        u = np.asarray(u, dtype=float)
        if u.ndim != 2 or u.shape[1] != 2:
            raise ValueError(f"u must be (m, 2), not {u.shape}")
        m = len(u)
        coef = _rows(coef, m, self.n_params, "coef", self.name)
        if self.constants and const is None:
            raise ValueError(f"camera model '{self.name}' needs the constants "
                             f"{', '.join(self.constants)}")
        const = (np.zeros((m, 0)) if not self.constants
                 else _rows(const, m, len(self.constants), "const", self.name))
        return self.terms(u, coef, const)


def _rows(a: ArrayLike | None, m: int, k: int, what: str, name: str) -> np.ndarray:
    if a is None:
        if k:
            raise ValueError(f"{what} of camera model '{name}' is missing")
        a = 0.0
    a = np.asarray(a, dtype=float)
    try:
        return np.broadcast_to(a, (m, k))
    except ValueError:
        raise ValueError(f"{what} of camera model '{name}' must be ({m}, {k}), "
                         f"not {a.shape}") from None


# ------------------------------------------------------------------ the building blocks
def _brown(u: np.ndarray, c: np.ndarray) -> Terms:
    """Brown terms of baarda's camera.py on u (m, 2) with c = (k1, k2, k3, p1, p2) (m, 5):
    delta (m, 2), d delta / du (m, 2, 2), d delta / dc (m, 2, 5)."""
    from baarda.block.lens_kernels import brown_rows

    m = len(u)
    delta, jac, dc = np.empty((m, 2)), np.empty((m, 2, 2)), np.empty((m, 2, 5))
    brown_rows(np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(c, dtype=float),
               delta, jac, dc)
    return delta, jac, dc


# ------------------------------------------------------------------ the models
def _none(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    m = len(u)
    return np.zeros((m, 2)), np.zeros((m, 2, 2)), np.zeros((m, 2, 0))


def _brown_fraser(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    delta, jac, dc = _brown(u, coef[:, :5])
    b1, b2 = coef[:, 5], coef[:, 6]
    delta[:, 0] += b1 * u[:, 0] + b2 * u[:, 1]
    jac[:, 0, 0] += b1
    jac[:, 0, 1] += b2
    dcoef = np.zeros((len(u), 2, 7))
    dcoef[:, :, :5] = dc
    dcoef[:, 0, 5] = u[:, 0]
    dcoef[:, 0, 6] = u[:, 1]
    return delta, jac, dcoef


def _dbat3(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    """DBAT model 3: ideal - pp = D(A u), A = [[1 + b1, b2], [0, 1]], D(w) = w + brown(w).

    delta = brown(w) + (A - I) u and d delta / du = brown'(w) A + (A - I), written so that
    nothing cancels when the coefficients are small."""
    b1, b2 = coef[:, 5], coef[:, 6]
    w = np.column_stack([(1 + b1) * u[:, 0] + b2 * u[:, 1], u[:, 1]])
    delta, bj, bc = _brown(w, coef[:, :5])
    delta[:, 0] += b1 * u[:, 0] + b2 * u[:, 1]
    jac = np.empty((len(u), 2, 2))
    jac[:, :, 0] = bj[:, :, 0] * (1 + b1)[:, None]
    jac[:, :, 1] = bj[:, :, 0] * b2[:, None] + bj[:, :, 1]
    jac[:, 0, 0] += b1
    jac[:, 0, 1] += b2
    jd0 = bj[:, :, 0].copy()  # d D / d w_x
    jd0[:, 0] += 1.0
    dcoef = np.empty((len(u), 2, 7))
    dcoef[:, :, :5] = bc
    dcoef[:, :, 5] = jd0 * u[:, 0:1]
    dcoef[:, :, 6] = jd0 * u[:, 1:2]
    return delta, jac, dcoef


def _dbat5(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    """DBAT model 5: ideal - pp = S D(A u), A = diag(1 + b1, 1), S = [[1, b2], [0, 1]].

    delta = S brown(w) + (S A - I) u and d delta / du = S brown'(w) A + (S A - I), with
    S A - I = [[b1, b2], [0, 0]]: nothing cancels when the coefficients are small."""
    b1, b2 = coef[:, 5], coef[:, 6]
    w = np.column_stack([(1 + b1) * u[:, 0], u[:, 1]])
    bd, bj, bc = _brown(w, coef[:, :5])
    ly = w[:, 1] + bd[:, 1]  # y after the lens distortion
    delta = bd.copy()
    delta[:, 0] += b1 * u[:, 0] + b2 * ly
    ja = bj.copy()
    ja[:, :, 0] *= (1 + b1)[:, None]  # brown'(w) A
    jac = ja.copy()
    jac[:, 0, :] += b2[:, None] * ja[:, 1, :]
    jac[:, 0, 0] += b1
    jac[:, 0, 1] += b2
    dcoef = np.empty((len(u), 2, 7))
    dcoef[:, :, :5] = bc
    dcoef[:, 0, :5] += b2[:, None] * bc[:, 1, :]
    dl_db1 = bj[:, :, 0] * u[:, 0:1]  # d D / d w_x * u_x
    dl_db1[:, 0] += u[:, 0]
    dcoef[:, :, 5] = dl_db1
    dcoef[:, 0, 5] += b2 * dl_db1[:, 1]
    dcoef[:, 0, 6] = ly
    dcoef[:, 1, 6] = 0.0
    return delta, jac, dcoef


def _brown_forward(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    """n_d = n + brown(n); u + delta = (n_d_x, (1 + a) n_d_y)."""
    a = coef[:, 5]
    bd, bj, bc = _brown(u, coef[:, :5])
    s = 1 + a
    delta = bd.copy()
    delta[:, 1] = s * bd[:, 1] + a * u[:, 1]
    jac = bj.copy()
    jac[:, 1, :] *= s[:, None]
    jac[:, 1, 1] += a
    dcoef = np.empty((len(u), 2, 6))
    dcoef[:, :, :5] = bc
    dcoef[:, 1, :5] *= s[:, None]
    dcoef[:, 0, 5] = 0.0
    dcoef[:, 1, 5] = u[:, 1] + bd[:, 1]
    return delta, jac, dcoef


def _fisheye_forward(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    """Equidistant fisheye on n = (ideal - pp)/c: theta = atan(r), r = |n|, theta_d =
    theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8), n_d = n theta_d / r, then
    the aspect a multiplies y by 1 + a (OpenSfM's fisheye and fisheye_opencv, OpenCV's
    fisheye model).  u + delta = (n_d_x, (1 + a) n_d_y)."""
    k, a = coef[:, :4], coef[:, 4]
    r2 = np.sum(u * u, axis=1)
    r = np.sqrt(r2)
    small = r < 1e-4
    rs = np.where(small, 1.0, r)
    th = np.arctan(r)
    t2 = th * th
    poly = 1 + t2 * (k[:, 0] + t2 * (k[:, 1] + t2 * (k[:, 2] + t2 * k[:, 3])))
    dpoly = 1 + t2 * (3 * k[:, 0] + t2 * (5 * k[:, 1] + t2 * (7 * k[:, 2] + t2 * 9 * k[:, 3])))
    # g = theta_d / r and h = (dg/dr) / r, by their series below r = 1e-4 (0/0 at r = 0)
    g = np.where(small, 1 + (k[:, 0] - 1 / 3) * r2, th * poly / rs)
    h = np.where(small, 2 * (k[:, 0] - 1 / 3),
                 (dpoly / (1 + r2) * rs - th * poly) / (rs * rs * rs))
    n = u * g[:, None]
    jn = g[:, None, None] * np.eye(2) + h[:, None, None] * u[:, :, None] * u[:, None, :]
    ratio = np.where(small, 1.0, th / rs)  # theta / r
    dk = np.stack([u * (ratio * t2 ** (j + 1))[:, None] for j in range(4)], axis=-1)
    s = 1 + a
    delta = n - u
    delta[:, 1] = s * n[:, 1] - u[:, 1]
    jac = jn - np.eye(2)
    jac[:, 1, :] = s[:, None] * jn[:, 1, :]
    jac[:, 1, 1] -= 1.0
    dcoef = np.zeros((len(u), 2, 5))
    dcoef[:, :, :4] = dk
    dcoef[:, 1, :4] *= s[:, None]
    dcoef[:, 1, 4] = n[:, 1]
    return delta, jac, dcoef


def _aicon(u: np.ndarray, coef: np.ndarray, const: np.ndarray) -> Terms:
    """AICON: radial A1..A3 with zero crossing r0, decentring B1, B2, affinity C1, C2."""
    x, y = u[:, 0], u[:, 1]
    a1, a2, a3, c1, c2 = coef[:, 0], coef[:, 1], coef[:, 2], coef[:, 5], coef[:, 6]
    r02 = const[:, 0] ** 2
    r2 = x * x + y * y
    dr = (r2 - r02, r2 * r2 - r02 * r02, r2**3 - r02**3)  # d radial / d A_i
    radial = a1 * dr[0] + a2 * dr[1] + a3 * dr[2]
    g = a1 + r2 * (2 * a2 + 3 * a3 * r2)
    # the decentring terms are Brown's with p1 = B1, p2 = B2
    td, tj, tc = _brown(u, np.column_stack([np.zeros((len(u), 3)), coef[:, 3:5]]))
    delta = td + u * radial[:, None]
    delta[:, 0] += c1 * x + c2 * y
    jac = tj
    jac[:, 0, 0] += radial + 2 * g * x * x + c1
    jac[:, 0, 1] += 2 * g * x * y + c2
    jac[:, 1, 0] += 2 * g * x * y
    jac[:, 1, 1] += radial + 2 * g * y * y
    dcoef = np.zeros((len(u), 2, 7))
    for i in range(3):
        dcoef[:, :, i] = u * dr[i][:, None]
    dcoef[:, :, 3:5] = tc[:, :, 3:5]
    dcoef[:, 0, 5] = x
    dcoef[:, 0, 6] = y
    return delta, jac, dcoef


# ------------------------------------------------------------------ the registry
BROWN_GROUPS = (("radial distortion", ("k1", "k2", "k3")),
                ("decentring distortion", ("p1", "p2")),
                ("affinity and shear", ("b1", "b2", "a")))

MODELS: dict[str, CameraModel] = {m.name: m for m in (
    CameraModel("none", "backward", (), (), False, "no distortion", _none, BROWN_GROUPS),
    CameraModel("brown", "backward", (*BROWN, "b1", "b2"), (), False,
                "Brown radial and decentring with affinity and shear (Fraser)", _brown_fraser,
                BROWN_GROUPS),
    CameraModel("dbat3", "backward", (*BROWN, "b1", "b2"), (), False,
                "DBAT model 3: affine [1+b1, b2; 0, 1] before Brown", _dbat3, BROWN_GROUPS),
    CameraModel("dbat5", "backward", (*BROWN, "b1", "b2"), (), False,
                "DBAT model 5: x scaled by 1+b1 before pp, Brown, skew b2 after", _dbat5,
                BROWN_GROUPS),
    CameraModel("brown_forward", "forward", (*BROWN, "a"), (), True,
                "Brown on normalised coordinates with aspect (OpenCV/COLMAP/BAL)",
                _brown_forward, BROWN_GROUPS),
    CameraModel("fisheye_forward", "forward", ("k1", "k2", "k3", "k4", "a"), (), True,
                "equidistant fisheye with odd polynomial in theta and aspect "
                "(OpenSfM/OpenCV fisheye)", _fisheye_forward,
                (("radial distortion", ("k1", "k2", "k3", "k4")), ("aspect", ("a",)))),
    CameraModel("aicon", "forward", ("a1", "a2", "a3", "b1", "b2", "c1", "c2"), ("r0",), False,
                "AICON 3D Studio: radial with zero crossing r0, decentring, affinity",
                _aicon, (("radial distortion", ("a1", "a2", "a3")),
                         ("decentring distortion", ("b1", "b2")),
                         ("affinity and shear", ("c1", "c2")))),
    CameraModel("ebner", "backward", tuple(f"b{i}" for i in range(1, 13)), ("b",), False,
                "Ebner's 12 orthogonal additional parameters (3x3 grid, spacing b)", ebner_terms),
    CameraModel("gruen", "backward", tuple(f"g{i}" for i in range(1, 45)), ("b",), False,
                "44 orthonormal fields of a 5x5 grid (spacing b), the space of Gruen's 44",
                gruen_terms),
)}


def get_model(name: str) -> CameraModel:
    """The model called name; ValueError naming the known models otherwise."""
    try:
        return MODELS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown camera model '{name}' (known: "
                         f"{', '.join(MODELS)})") from None


def apply(model: CameraModel, u: ArrayLike, coef: ArrayLike | None,
          const: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """u + delta(u) (m, 2) and its Jacobian I + d delta / du (m, 2, 2)."""
    delta, jac, _ = model.correction(u, coef, const)
    return np.asarray(u, dtype=float) + delta, jac + np.eye(2)


def apply_forward(model: CameraModel, u: ArrayLike, coef: ArrayLike | None,
                  const: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """`apply` for a forward model: projected = pp + s (u + delta(u)), s = c if normalized."""
    if model.side != "forward":
        raise ValueError(f"camera model '{model.name}' is a backward model")
    return apply(model, u, coef, const)


def invert(model: CameraModel, target: ArrayLike, coef: ArrayLike | None,
           const: ArrayLike | None = None, iterations: int = 20,
           groups: np.ndarray | None = None) -> np.ndarray:
    """u (m, 2) with u + delta(u) = target (m, 2), by Newton's method (one 2x2 system per
    row; for approximations and writers).  Backward models: the reduced observation whose
    correction is target; forward: the reduced ideal coordinate that projects to target.
    groups (m,): rows iterated until the largest step of their group (a camera) is
    negligible, each group as if alone (default: one group)."""
    target = np.asarray(target, dtype=float)
    m = len(target)
    u = target.copy()
    groups = np.zeros(m, np.int64) if groups is None else np.asarray(groups, np.int64)
    ng = int(groups.max()) + 1 if m else 0
    big = np.zeros(ng)
    np.maximum.at(big, groups, np.max(np.abs(target), axis=1, initial=0.0))
    tol = 1e-14 * np.maximum(1.0, big)
    coef = None if coef is None else np.broadcast_to(np.asarray(coef, float),
                                                     (m, model.n_params))
    const = None if const is None else np.broadcast_to(np.asarray(const, float),
                                                       (m, len(model.constants)))
    rows = np.arange(m)
    for _ in range(iterations):
        if not len(rows):
            break
        every = len(rows) == m
        ur = u if every else u[rows]
        delta, jac, _ = model.correction(
            ur, coef if coef is None or every else coef[rows],
            const if const is None or every else const[rows])
        jac += np.eye(2)
        step = np.linalg.solve(jac, ((target if every else target[rows]) - ur - delta)
                               [:, :, None])[:, :, 0]
        u[rows] += step
        largest = np.zeros(ng)
        np.maximum.at(largest, groups[rows], np.abs(step).max(axis=1))
        rows = rows[~(largest <= tol)[groups[rows]]]
    return u


# ------------------------------------------------------------------ DBAT's principal point
def principal_point_from_dbat(pp_dbat: ArrayLike, b1: ArrayLike, format_mm: ArrayLike,
                              model: str = "dbat5") -> np.ndarray:
    """baarda's principal point (n, 2) [mm, image centre, y up] of DBAT's pp (n, 2) [mm from
    the upper-left image corner, y down, as in DBAT's camera files and reports], DBAT's
    aspect parameter b1 ('as', (n,)) and the format (W, H) (n, 2) [mm].

    dbat5 scales x by 1 + b1 before DBAT subtracts pp: x0 = pp_x / (1 + b1) - W/2;
    dbat3 (affine after pp): x0 = pp_x - W/2.  Both: y0 = H/2 - pp_y.
    """
    pp_dbat, fmt = np.atleast_2d(pp_dbat).astype(float), np.atleast_2d(format_mm)
    sx = _dbat_scale(b1, model)
    return np.column_stack([pp_dbat[:, 0] / sx - fmt[:, 0] / 2, fmt[:, 1] / 2 - pp_dbat[:, 1]])


def principal_point_to_dbat(pp: ArrayLike, b1: ArrayLike, format_mm: ArrayLike,
                            model: str = "dbat5") -> np.ndarray:
    """DBAT's pp (n, 2) of baarda's principal point pp (n, 2): inverse of
    `principal_point_from_dbat`."""
    pp, fmt = np.atleast_2d(pp).astype(float), np.atleast_2d(format_mm)
    sx = _dbat_scale(b1, model)
    return np.column_stack([(pp[:, 0] + fmt[:, 0] / 2) * sx, fmt[:, 1] / 2 - pp[:, 1]])


def _dbat_scale(b1: ArrayLike, model: str) -> np.ndarray:
    if model == "dbat5":
        return 1.0 + np.asarray(b1, dtype=float)
    if model == "dbat3":
        return np.ones_like(np.asarray(b1, dtype=float))
    raise ValueError(f"not a DBAT model: '{model}' (dbat3, dbat5)")
