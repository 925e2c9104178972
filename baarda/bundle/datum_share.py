"""Which datum directions of a free network its GNSS positions, IMU attitudes and distances
already fix, and which are left to minimal constraints.

A block without control has seven datum directions: three translations, three rotations
(about the centroid of the approximate projection centres) and a scale.  Image points fix
none of them; distances fix the scale; GNSS positions fix translation, scale and the
rotations their positions span (three positions not on a line: all seven; positions on a
line leave the roll about it free); IMU attitudes fix the rotations.  GNSS shifts and drifts
and the IMU boresight are unknowns of their own that take back what they absorb (a GNSS
shift per block: the translation).

With A (rows x d) the derivatives of those observations along each datum direction, W their
weights and B the derivatives along their own unknowns, the information on the datum is

    F = A'WA - A'WB (B'WB)^+ B'WA      (d x d),

its eigenvectors the directions, 1 / sqrt(eigenvalue) their standard deviations.  The
rotation and scale directions are measured in metres at the block's extent E (the RMS
distance of the approximate projection centres and points from their centroid), so that
every standard deviation is the movement of the block's far points.

A direction is *free* when its eigenvalue is zero (below 1e-9 of the largest): minimal
constraints hold exactly these, and the statistics do not depend on which.  It is *weak*
when it is determined, but more than WEAK times worse than the best-determined one (three
GNSS positions close to a line: the roll about it): holding it by a constraint would
over-constrain the observations (statistics depending on the constraint), leaving it to
them gives a datum that they fix only in name.  pipeline._prepare then leaves those
observations out of a free network (a note says so); `--datum control` uses them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.block.photo_block import Block
from baarda.bundle.inner_datum import angle_directions, position_directions

DIRECTIONS = ("translation X", "translation Y", "translation Z", "rotation about X",
              "rotation about Y", "rotation about Z", "scale")
FREE = 1e-9  # an eigenvalue below this share of the largest: not determined at all
WEAK = 10.0  # a direction determined this many times worse than the best one is weak


@dataclass(frozen=True)
class DatumShare:
    """What the non-image observations fix of a free network's datum.

    d: 7, or 6 when distances fix the scale; free (d, k): a basis of the directions left to
    minimal constraints (unscaled: translations in m, rotations in rad, scale per unit);
    sd (d - k,) m: the standard deviation of each determined direction at the extent;
    weak: the determined directions more than WEAK times worse than the best, in words;
    extent m; sources: the observations that fix the determined directions ("GNSS
    positions", "IMU attitudes", "distances"), `by` the same in words."""

    d: int
    free: np.ndarray
    sd: np.ndarray
    weak: tuple[str, ...]
    extent: float
    sources: tuple[str, ...]

    @property
    def by(self) -> str:
        """What fixes the determined directions, in words ("" when nothing does)."""
        return " and ".join(self.sources)

    @property
    def carried(self) -> int:
        """The number of datum directions the observations fix."""
        return self.d - self.free.shape[1]


def _describe(v: np.ndarray, names: tuple[str, ...]) -> str:
    """A direction (unit vector over the named directions) in words: its largest parts."""
    a = np.abs(v) / max(float(np.abs(v).max()), 1e-300)
    parts = [names[i] for i in np.argsort(-a) if a[i] >= 0.3]
    return " and ".join(parts[:3])


def datum_share(block: Block) -> DatumShare:
    """What the GNSS positions, IMU attitudes and distances of `block` (its approximations
    in a local frame) fix of its free-network datum (module docstring)."""
    from baarda.bundle.gnss_imu import GnssImu

    scaled = bool(len(block.distances))
    d = 6 if scaled else 7
    names = DIRECTIONS[:d]
    eo = block.photos.eo
    by = tuple(w for w, n in (("GNSS positions", len(block.gnss)),
                              ("IMU attitudes", len(block.imu)),
                              ("distances", len(block.distances))) if n)
    ok = np.isfinite(eo).all(axis=1)
    centres = eo[ok, :3]
    pts = block.points.xyz[np.isfinite(block.points.xyz).all(axis=1)]
    centre = centres.mean(axis=0) if len(centres) else np.zeros(3)
    both = np.vstack([centres, pts]) if len(pts) else centres
    extent = float(np.sqrt(np.mean(np.sum((both - centre) ** 2, axis=1)))) if len(both) else 1.0
    extent = max(extent, 1e-9)
    gi = GnssImu(block, 0)
    if not gi.m:
        free = np.eye(d)
        return DatumShare(d, free, np.zeros(0), (), extent, by)
    photos = gi.photos
    e0 = np.where(ok[:, None], eo, 0.0)
    _, jxf, jxg = gi.rows(e0, np.zeros(gi.n), gi.n)
    # datum directions of every photo's six unknowns (scale kept: dropped below if fixed)
    gf = np.zeros((len(eo), 6, 7))
    gf[:, :3] = position_directions(e0[:, :3], centre, True)
    gf[:, 3:, 3:6] = angle_directions(e0[:, 3:])
    unit = np.array([1, 1, 1, extent, extent, extent, extent], float)[:d]
    a = np.einsum("rk,rkd->rd", jxf[:, 0], gf[photos][:, :, :d]) / unit
    b = jxg[:, 0]
    w = 1.0 / gi.sigma ** 2
    f = a.T @ (w[:, None] * a)
    if b.shape[1]:
        fb = a.T @ (w[:, None] * b)
        f = f - fb @ np.linalg.pinv(b.T @ (w[:, None] * b)) @ fb.T
    lam, vec = np.linalg.eigh((f + f.T) / 2)
    top = max(float(lam.max()), 0.0)
    is_free = lam <= FREE * top if top > 0 else np.ones(d, bool)
    sd = 1.0 / np.sqrt(lam[~is_free])
    weak = tuple(f"{_describe(vec[:, i], names)} (standard deviation {s:.3g} m at the "
                 f"block's extent {extent:.3g} m)"
                 for i, s in zip(np.flatnonzero(~is_free), sd, strict=True)
                 if len(sd) and s > WEAK * sd.min())
    free = vec[:, is_free] / unit[:, None]  # back to m, rad and scale per unit
    free = free / np.linalg.norm(free, axis=0, keepdims=True) if free.shape[1] else free
    return DatumShare(d, free, sd, weak, extent, by)


def minimal_constraints(block: Block, share: DatumShare, first: int, second: int
                        ) -> np.ndarray:
    """(n_photos, 6) bool: the orientation unknowns held to fix exactly the free directions
    of `share`: chosen among photo `first`'s six and photo `second`'s position by a pivoted
    QR of their datum directions restricted to the free ones (the best-conditioned set)."""
    from scipy.linalg import qr

    eo = block.photos.eo
    k = share.free.shape[1]
    held = np.zeros((len(eo), 6), bool)
    if k == 0:
        return held
    ok = np.isfinite(eo).all(axis=1)
    centre = eo[ok, :3].mean(axis=0)
    g = np.zeros((2, 6, 7))
    g[:, :3] = position_directions(eo[[first, second], :3], centre, True)
    g[:, 3:, 3:6] = angle_directions(eo[[first, second], 3:])
    cand = np.vstack([g[0], g[1, :3]])[:, :share.d]  # 9 candidate unknowns
    at_extent = np.array([1, 1, 1, share.extent, share.extent, share.extent, 1, 1, 1])
    c = (cand * at_extent[:, None]) @ share.free  # each unknown's move, m at the extent
    _, _, piv = qr(c.T, pivoting=True)
    pick = piv[:k]
    if np.linalg.svd(c[pick], compute_uv=False).min() < 1e-6 * np.abs(c).max():
        from baarda.errors import GeometryError

        raise GeometryError("the datum directions left free cannot be held by the unknowns "
                            "of two photos (the photos coincide)")
    for p in pick:
        held[first if p < 6 else second, p if p < 6 else p - 6] = True
    return held
