"""Lens distortion of a camera: the kinds of model and their (fixed) coefficients.

Every camera carries a model kind and five coefficients k1, k2, k3, p1, p2 (Brown 1971:
three radial, two decentring terms).  Image coordinates are in mm in baarda's image frame
(x right, y up, origin where the reader put it); the principal point pp and the camera
constant c are those of `Cameras`.  With u = (x, y) and r^2 = x^2 + y^2 the Brown terms are

    delta(u) = u (k1 r^2 + k2 r^4 + k3 r^6) + [p1 (r^2 + 2 x^2) + 2 p2 x y,
                                               2 p1 x y + p2 (r^2 + 2 y^2)]

Kinds:

* ``none``: no distortion (coefficients ignored).
* ``brown_backward``: the photogrammetric "correction of observed coordinates" (DBAT's
  backward model 3, PhotoModeler with negated coefficients): u = observed - pp in mm,
  ideal = pp + u + delta(u); k1 in mm^-2, k2 mm^-4, k3 mm^-6, p1, p2 mm^-1.  Because it
  depends on the observation only, baarda applies it once to the observations
  (`ideal_image_coordinates`); the projection itself is undistorted.  With fixed
  coefficients this is exactly the residual DBAT forms (projection - corrected observation,
  weighted with the observation's a-priori sigma).
* ``brown_forward``: the computer-vision model applied in the projection to normalised
  coordinates n = (ideal - pp) / c (dimensionless coefficients): projected = pp +
  c (n + delta(n)).  BAL's radial model is k1, k2 with k3 = p1 = p2 = 0.  OpenCV/COLMAP
  write the decentring terms the other way round (dx = 2 p1 x y + p2 (r^2 + 2 x^2)) with y
  down, so their (p1, p2) are baarda's (p2, -p1).

Self-calibration (estimating these coefficients) is not implemented; the structure keeps
the coefficients per camera so that it can be added.
"""

from __future__ import annotations

import numpy as np

KINDS = ("none", "brown_backward", "brown_forward")
COEFFICIENTS = ("k1", "k2", "k3", "p1", "p2")


def brown_terms(u: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """delta(u) (m, 2) and its Jacobian d delta / d u (m, 2, 2) for coefficients d (m, 5)."""
    x, y = u[:, 0], u[:, 1]
    k1, k2, k3, p1, p2 = (d[:, i] for i in range(5))
    r2 = x * x + y * y
    radial = r2 * (k1 + r2 * (k2 + r2 * k3))
    g = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
    delta = np.empty_like(u)
    delta[:, 0] = x * radial + p1 * (r2 + 2 * x * x) + 2 * p2 * x * y
    delta[:, 1] = y * radial + 2 * p1 * x * y + p2 * (r2 + 2 * y * y)
    jac = np.empty((len(u), 2, 2))
    cross = 2 * g * x * y + 2 * p1 * y + 2 * p2 * x
    jac[:, 0, 0] = radial + 2 * g * x * x + 6 * p1 * x + 2 * p2 * y
    jac[:, 0, 1] = cross
    jac[:, 1, 0] = cross
    jac[:, 1, 1] = radial + 2 * g * y * y + 2 * p1 * x + 6 * p2 * y
    return delta, jac


def camera_arrays(cameras) -> tuple[np.ndarray, np.ndarray]:
    """(kinds (n,) object, coefficients (n, 5)) of `Cameras`, defaults where not given."""
    n = len(cameras)
    kinds = getattr(cameras, "model", None)
    coef = getattr(cameras, "distortion", None)
    kinds = (np.full(n, "none", dtype=object) if kinds is None
             else np.asarray(kinds, dtype=object))
    coef = np.zeros((n, 5)) if coef is None else np.asarray(coef, float).reshape(n, 5)
    bad = [k for k in kinds if k not in KINDS]
    if bad:
        raise ValueError(f"unknown camera model '{bad[0]}' (known: {', '.join(KINDS)})")
    return kinds, coef


def forward_coefficients(cameras, camera_of_row: np.ndarray) -> np.ndarray | None:
    """Coefficients (m, 5) of the forward model per row (zeros elsewhere), or None if unused."""
    kinds, coef = camera_arrays(cameras)
    fwd = kinds == "brown_forward"
    if not fwd.any():
        return None
    return np.where(fwd[:, None], coef, 0.0)[camera_of_row]


def distort(xy_ideal: np.ndarray, pp: np.ndarray, focal: np.ndarray,
            d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward model: projected coordinates (m, 2) and d projected / d ideal (m, 2, 2)."""
    n = (xy_ideal - pp) / focal[:, None]
    delta, jac = brown_terms(n, d)
    jac[:, 0, 0] += 1.0
    jac[:, 1, 1] += 1.0
    return pp + focal[:, None] * (n + delta), jac


def _invert(target: np.ndarray, d: np.ndarray, iterations: int = 20) -> np.ndarray:
    """u with u + delta(u) = target (m, 2) for coefficients d (m, 5), by Newton's method."""
    u = target.copy()
    for _ in range(iterations):
        delta, jac = brown_terms(u, d)
        jac[:, 0, 0] += 1.0
        jac[:, 1, 1] += 1.0
        step = np.linalg.solve(jac, (target - u - delta)[:, :, None])[:, :, 0]
        u += step
        if np.max(np.abs(step), initial=0.0) < 1e-15:
            break
    return u


def undistort(xy: np.ndarray, pp: np.ndarray, focal: np.ndarray, d: np.ndarray,
              iterations: int = 20) -> np.ndarray:
    """Inverse of `distort` (for approximations and writers)."""
    return pp + focal[:, None] * _invert((xy - pp) / focal[:, None], d, iterations)


def correct_backward(xy: np.ndarray, pp: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Backward model: ideal coordinates pp + u + delta(u) of observed xy (m, 2), u = xy - pp."""
    u = xy - pp
    delta, _ = brown_terms(u, d)
    return pp + u + delta


def uncorrect_backward(xy_ideal: np.ndarray, pp: np.ndarray, d: np.ndarray,
                       iterations: int = 20) -> np.ndarray:
    """Inverse of `correct_backward`: the observation whose correction is xy_ideal."""
    return pp + _invert(xy_ideal - pp, d, iterations)


def corrected_observations(block) -> np.ndarray:
    """The observations (m, 2) in mm as the adjustment compares them with the projection:
    backward-model rows corrected, all other rows as observed."""
    im = block.image
    kinds, coef = camera_arrays(block.cameras)
    cam = block.photos.camera[im.photo]
    out = np.array(im.xy_mm, dtype=float, copy=True)
    back = kinds[cam] == "brown_backward"
    if back.any():
        pp = block.cameras.principal_point_mm[cam[back]]
        out[back] = correct_backward(out[back], pp, coef[cam[back]])
    return out


def ideal_image_coordinates(block) -> np.ndarray:
    """Image coordinates (m, 2) in mm free of distortion, for every row of block.image.

    Backward model: the corrected observations.  Forward model: the undistorted
    observations (for approximations only: the adjustment applies the forward model in the
    projection and compares with `corrected_observations`).
    """
    im = block.image
    kinds, coef = camera_arrays(block.cameras)
    cam = block.photos.camera[im.photo]
    out = corrected_observations(block)
    pp = block.cameras.principal_point_mm[cam]
    fwd = kinds[cam] == "brown_forward"
    if fwd.any():
        out[fwd] = undistort(out[fwd], pp[fwd], block.cameras.focal_mm[cam[fwd]],
                             coef[cam[fwd]])
    return out
