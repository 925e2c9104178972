"""Simulated blocks with GNSS positions and IMU attitudes of known truth (tests only)."""

from dataclasses import replace

import numpy as np

from baarda.block.photo_block import GnssObservations, ImuObservations
from baarda.block.rotation import rotation_matrix
from baarda.bundle.gnss_imu import attitude


def true_eo(block, truth) -> np.ndarray:
    keys = ("X0", "Y0", "Z0", "omega", "phi", "kappa")
    return np.array([[truth["photos"][p][k] for k in keys] for p in block.photos.ids])


def with_gnss(block, truth, *, sigma_m=0.05, sigma_rad=1e-4, lever=(0.1, -0.2, 1.0),
              offsets="none", drift=False, boresight="fixed", seed=0,
              shift_by_strip=None, true_boresight=(0.0, 0.0, 0.0), imu=True):
    """The block with GNSS antenna positions (lever arm, optional true shifts per strip)
    and IMU attitudes (optional true boresight), normally distributed errors."""
    rng = np.random.default_rng(seed)
    eo = true_eo(block, truth)
    n = len(eo)
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    ant = eo[:, :3] + r @ np.asarray(lever, float)
    if shift_by_strip:
        strips = np.asarray([str(s) for s in block.photos.strip], dtype=object)
        for lab, shift in shift_by_strip.items():
            ant[strips == lab] += np.asarray(shift, float)
    ant += rng.normal(0.0, sigma_m, (n, 3))
    gnss = GnssObservations(np.arange(n), ant, np.full((n, 3), sigma_m))
    settings = replace(block.settings, gnss_lever_arm=tuple(lever), gnss_offsets=offsets,
                       gnss_drift=drift, imu_boresight=boresight)
    out = replace(block, gnss=gnss, settings=settings)
    if imu:
        ang = attitude(eo[:, 3:], np.asarray(true_boresight, float))[0]
        ang += rng.normal(0.0, sigma_rad, (n, 3))
        out = replace(out, imu=ImuObservations(np.arange(n), ang, np.full((n, 3), sigma_rad)))
    return out


def gnss_imu_block_with_a_distance():
    """A simulated block with GNSS positions (a shift per strip), IMU attitudes and one
    distance between two tie points (its true length, sigma 0.01 m): every kind of
    observation row at once; (block, truth)."""
    from baarda.block.photo_block import Distances
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, truth = simulate_block(FlightPlan(strips=2, photos_per_strip=6, seed=5,
                                             gnss_sigma_m=0.05, gnss_offset_m=0.3,
                                             imu_sigma_deg=0.005))
    pts = block.points
    tie = np.flatnonzero(pts.role == "tie")
    a, b = tie[1], tie[-2]
    xa, xb = (np.array(truth["points"][pts.ids[j]]) for j in (a, b))
    dist = Distances(["bar"], np.array([a]), np.array([b]),
                     np.array([float(np.linalg.norm(xa - xb))]), np.array([0.01]))
    return replace(block, distances=dist), truth
