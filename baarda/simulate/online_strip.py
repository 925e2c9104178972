"""A simulated strip for on-line bridging, with known truth.

Units: everything at photo scale in mm (ground coordinates too, so the true model
coordinates of the strip are the ground coordinates).  Photo k has its projection centre
near (k b, 0, 0) and a small random attitude; photo 0 is exactly at the origin without
rotation (the strip frame of OnlineSession).  Every model uses the same point pattern
(baarda.block.point_patterns); a point in the right column of model k is the point in the
left column of model k+1 (same id).  Ids: 10 (j + 1) + row for column j of the strip, a twin
gets a "'".  Noise is put on the right image coordinates only, as the model assumes (the
left ones are fixed in parallax mode): sigma_x on x'', sqrt(qyy) sigma_x on y''.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.block.point_patterns import standard_pattern
from baarda.block.rotation import rotation_matrix


@dataclass
class SimulatedStrip:
    models: list[tuple[str, dict[str, tuple[float, float, float, float]]]]
    centres: np.ndarray  # (k + 1, 3) true projection centres
    rotations: np.ndarray  # (k + 1, 3, 3)
    points: dict[str, np.ndarray]  # true strip coordinates
    base: float  # true b_x of the first model


def simulate_strip(n_models: int = 3, pattern: str = "9", focal: float = 152.0,
                   base: float = 92.0, width: float = 92.0, relief: float = 4.0,
                   sigma_x: float = 5.0, qyy: float = 2.0, attitude: float = 0.01,
                   position: float = 0.02, seed: int = 0) -> SimulatedStrip:
    """Models "1-2", "2-3", ...; relief: sd of heights (mm); attitude: sd of angles (rad);
    position: sd of the projection centres off the ideal line, in bases (half of it in Z)."""
    rng = np.random.default_rng(seed)
    pts = standard_pattern(pattern, 0, base, width)
    xs = sorted({p.x for p in pts})
    ncol = len(xs)
    centres = np.zeros((n_models + 1, 3))
    rots = np.zeros((n_models + 1, 3, 3))
    rots[0] = np.eye(3)
    for k in range(1, n_models + 1):
        centres[k] = [k * base + rng.normal(0, position * base),
                      rng.normal(0, position * base), rng.normal(0, 0.5 * position * base)]
        rots[k] = rotation_matrix(*rng.normal(0, attitude, 3))
    ground: dict[str, np.ndarray] = {}
    models = []
    for k in range(n_models):
        meas = {}
        for p in pts:
            ci = xs.index(p.x)
            j = k * (ncol - 1) + ci
            row = [q for q in pts if q.x == p.x and q.twin_of is None].index(
                next(q for q in pts if q.name == (p.twin_of or p.name)))
            pid = f"{10 * (j + 1) + row + 1}" + ("'" if p.twin_of else "")
            if pid not in ground:
                ground[pid] = np.array([k * base + p.x, p.y, -focal + rng.normal(0, relief)])
            xy = [_project(ground[pid], centres[i], rots[i], focal) for i in (k, k + 1)]
            noise = rng.normal(0, 1e-3 * sigma_x, 2) * [1.0, np.sqrt(qyy)]
            meas[pid] = (xy[0][0], xy[0][1], xy[1][0] + noise[0], xy[1][1] + noise[1])
        models.append((f"{k + 1}-{k + 2}", meas))
    return SimulatedStrip(models, centres, rots, ground, float(centres[1, 0]))


def _project(xyz: np.ndarray, centre: np.ndarray, rot: np.ndarray, c: float) -> np.ndarray:
    u = rot.T @ (xyz - centre)
    return np.array([-c * u[0] / u[2], -c * u[1] / u[2]])


def online_text(strip: SimulatedStrip, focal: float, sigma_x: float) -> str:
    """The strip as a `baarda online` measurement file (docs/online.md)."""
    lines = ["# simulated strip (baarda.simulate.online_strip)",
             f"camera focal={focal:g} sigma={sigma_x:g}"]
    for k, (name, meas) in enumerate(strip.models):
        lines.append(f"model {name}" + (f" base={strip.base:.6f}" if k == 0 else ""))
        lines += [f"{p} {v[0]:.6f} {v[1]:.6f} {v[2]:.6f} {v[3]:.6f}" for p, v in meas.items()]
        lines.append("end")
    return "\n".join(lines) + "\n"
