"""The test block of Lugnani & Mitishita: 3 strips x 4 photos with their Table 1 blunders.

1:10 000, c = 153 mm, 23 cm format, 60 % forward and 20 % side overlap: the base is 920 m
and the strips are 1840 m apart.  The ground points lie on a grid of half bases along the
strips and of rows at the strip centres and in the side overlaps (one row outside each outer
strip); three grid places are left empty so that the block has exactly 46 ground points
(8 full control points, numbered 7xx) and 134 image points, as in the paper.  Positions are
jittered, the terrain has 15 m of relief, the photos small tilts.

The blunders are those of the paper's Table 1, kind and size; the points are ours, chosen
where the paper's photo coordinates put them (a nadir point, a side-overlap point, ...);
PAPER_IDS maps our numbers to theirs.  The control errors are at two opposite block corners,
like the paper's 772 and 745.
"""

from __future__ import annotations

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.bundle.collinearity import project

SCALE, FOCAL, FORMAT = 10_000.0, 153.0, 230.0
BASE = (1 - 0.60) * FORMAT * 1e-3 * SCALE  # 920 m
SPACING = (1 - 0.20) * FORMAT * 1e-3 * SCALE  # 1840 m between strips
ROWS = [-0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5]  # in strip spacings: outer, centre, overlap, ...
COLUMNS = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0]  # in bases
EMPTY = {(2, 0.5), (4, 1.5), (6, 2.5)}  # grid places without a point: 46 points, 134 rays
# full control: three along each outer row (the height of each strip across its axis is
# then checked) and one in each side overlap; strip 2 has two (not checked in stage 3)
CONTROL = {(0, 0.0): "701", (0, 1.5): "702", (0, 3.0): "703", (2, 0.0): "704",
           (4, 3.0): "705", (6, 0.0): "706", (6, 1.5): "707", (6, 3.0): "708"}
SIGMA_IMAGE_UM = 3.0
SIGMA_CONTROL_M = 0.05


def _tie_ids() -> dict[tuple[int, float], str]:
    out, tie = {}, 601
    for r in range(len(ROWS)):
        for col in COLUMNS:
            if (r, col) not in EMPTY and (r, col) not in CONTROL:
                out[(r, col)] = str(tie)
                tie += 1
    return out


TIE = _tie_ids()
# (grid place, photo, dx mm, dy mm): the photo-coordinate errors of Table 1
_IMAGE = [((1, 1.0), "1", 0.100, -0.100),  # 642: a nadir point of the next photo
          ((1, 2.0), "2", 24.000, 0.0),  # 669: nadir of photo 3, seen on 2, 3, 4
          ((1, 2.0), "4", 0.0, 0.040),
          ((2, 3.0), "7", 0.0, -0.050),  # 622: side overlap, y = -92 mm on photo 7
          ((4, 0.0), "9", -0.100, -17.000),  # 627: side overlap at the nadir of photo 9
          ((5, 1.0), "10", -4.532, -0.070),  # 636: nadir of photo 10
          ((5, 2.0), "11", -0.061, 0.0),  # 640: nadir of photo 11
          ((5, 3.0), "12", -0.030, 0.030)]  # 626: nadir of photo 12 (two rays)
IMAGE_BLUNDERS = [(TIE[g], f, dx, dy) for g, f, dx, dy in _IMAGE]
# (point, dX, dY, dZ in m): the control errors of Table 1
CONTROL_BLUNDERS = [("706", -1.0, 0.0, -2.0), ("703", 0.0, 0.0, -3.0)]
PAPER_IDS = dict(zip([p for p, *_ in IMAGE_BLUNDERS], ["642", "669", "669", "622", "627",
                                                       "636", "640", "626"], strict=True))
PAPER_IDS.update({"706": "772", "703": "745"})


def _layout(rng: np.random.Generator):
    ids, xyz, role = [], [], []
    for r, row in enumerate(ROWS):
        for col in COLUMNS:
            if (r, col) in EMPTY:
                continue
            x = col * BASE + rng.uniform(-40, 40)
            y = row * SPACING + rng.uniform(-40, 40)
            z = (970.0 + 9.0 * np.sin(x / 700.0 + 0.3) * np.cos(y / 900.0)
                 + 6.0 * np.sin(y / 1300.0 + 1.0) + rng.normal(0, 1.5))
            if (r, col) in CONTROL:
                ids.append(CONTROL[(r, col)])
                role.append("control")
            else:
                ids.append(TIE[(r, col)])
                role.append("tie")
            xyz.append((x, y, z))
    return ids, np.array(xyz), np.array(role, dtype=object)


def build(seed: int = 1, blunders: bool = True) -> tuple[Block, dict]:
    """The block (approximate orientations, noisy observations) and the truth.

    The noise is the same with and without blunders (same seed), so the noise-only block
    is the reference for the accuracy reached after cleaning.
    """
    rng = np.random.default_rng(seed)
    ids, xyz, role = _layout(rng)
    n_ph = 12
    strip = np.repeat(np.arange(3), 4)
    along = np.tile(np.arange(4), 3)
    height = 970.0 + FOCAL * 1e-3 * SCALE
    eo = np.column_stack([along * BASE + rng.normal(0, 10, n_ph),
                          strip * SPACING + rng.normal(0, 10, n_ph),
                          height + rng.normal(0, 5, n_ph),
                          rng.normal(0, 0.01, n_ph), rng.normal(0, 0.01, n_ph),
                          rng.normal(0, 0.01, n_ph)])
    half = 0.5 * FORMAT * 1e-3 * SCALE
    rel = xyz[None, :, :2] - eo[:, None, :2]
    seen = (np.abs(rel) < half - 60).all(axis=2)
    ph, pt = np.nonzero(seen)
    xy = project(eo[ph], xyz[pt], np.full(len(ph), FOCAL), np.zeros((len(ph), 2)))
    sig = SIGMA_IMAGE_UM * 1e-3
    xy = xy + rng.normal(0, sig, xy.shape)
    given = xyz + rng.normal(0, SIGMA_CONTROL_M, xyz.shape)
    photo_ids = [str(i + 1) for i in range(n_ph)]
    index = {p: i for i, p in enumerate(ids)}
    log = []
    if blunders:
        for p, f, dx, dy in IMAGE_BLUNDERS:
            row = np.flatnonzero((ph == int(f) - 1) & (pt == index[p]))
            assert len(row) == 1, (p, f)
            xy[row[0]] += (dx, dy)
            log.append({"kind": "image", "point": p, "photo": f, "dx_mm": dx, "dy_mm": dy})
        for p, dx, dy, dz in CONTROL_BLUNDERS:
            given[index[p]] += (dx, dy, dz)
            log.append({"kind": "control", "point": p, "dX": dx, "dY": dy, "dZ": dz})
    eo_approx = eo.copy()
    eo_approx[:, :3] += rng.normal(0, 5.0, (n_ph, 3))
    eo_approx[:, 3:] += rng.normal(0, 0.01, (n_ph, 3))
    ctrl = role == "control"
    gxyz = np.where(ctrl[:, None], given, np.nan)
    gsig = np.where(ctrl[:, None], np.full(xyz.shape, SIGMA_CONTROL_M), np.nan)
    settings = Settings(name="lugnani", angle_unit="gon", sigma_image_um=SIGMA_IMAGE_UM,
                        sigma_control_m=(SIGMA_CONTROL_M,) * 3)
    block = Block(settings, Cameras(["rmk"], np.array([FOCAL]), np.zeros((1, 2))),
                  Photos(photo_ids, np.zeros(n_ph, np.int64),
                         np.array([str(s + 1) for s in strip], dtype=object), eo_approx),
                  ImagePoints(ph.astype(np.int64), pt.astype(np.int64), xy,
                              np.full(len(ph), sig)),
                  GroundPoints(ids, gxyz, gsig, role), source="lugnani")
    truth = {"points": {p: xyz[i] for i, p in enumerate(ids)},
             "photos": {p: eo[i] for i, p in enumerate(photo_ids)}, "blunders": log}
    return block, truth
