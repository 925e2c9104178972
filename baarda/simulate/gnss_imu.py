"""GNSS antenna positions and IMU attitudes of a simulated aerial block (see FlightPlan's
gnss_* and imu_* fields)."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from baarda.block.photo_block import Block, GnssObservations, ImuObservations

if TYPE_CHECKING:
    from baarda.simulate.aerial import FlightPlan


def with_gnss_imu(plan: FlightPlan, block: Block, eo_true: np.ndarray) -> tuple[Block, dict]:
    """GNSS antenna positions (lever arm 0) and IMU attitudes of every photo, with their
    errors drawn from a random stream of their own (the rest of the block is as without)."""
    rng = np.random.default_rng([plan.seed, 14])
    n = len(eo_true)
    strips = np.asarray(block.photos.strip, dtype=object)
    labels = sorted(set(strips.tolist()), key=int)
    truth: dict = {"shift": {}, "drift_m_per_km": {}}
    settings = block.settings
    if plan.gnss_sigma_m > 0:
        pos = eo_true[:, :3].copy()
        for lab in labels:
            sel = strips == lab
            shift = rng.normal(0.0, plan.gnss_offset_m, 3) if plan.gnss_offset_m else np.zeros(3)
            drift = (rng.normal(0.0, plan.gnss_drift_m_per_km, 3) if plan.gnss_drift_m_per_km
                     else np.zeros(3))
            xy = eo_true[sel, :2]
            d = xy - xy.mean(axis=0)
            u = np.linalg.svd(d, full_matrices=False)[2][0] if len(d) > 1 else np.array([1, 0])
            pos[sel] += shift + np.outer(d @ u / 1000.0, drift)
            truth["shift"][lab] = shift.tolist()
            truth["drift_m_per_km"][lab] = drift.tolist()
        pos += rng.normal(0.0, plan.gnss_sigma_m, (n, 3))
        block = replace(block, gnss=GnssObservations(np.arange(n), pos,
                                                     np.full((n, 3), plan.gnss_sigma_m)))
        settings = replace(settings, gnss_offsets="strip" if plan.gnss_offset_m else "none",
                           gnss_drift=bool(plan.gnss_drift_m_per_km))
    if plan.imu_sigma_deg > 0:
        s = np.radians(plan.imu_sigma_deg)
        ang = eo_true[:, 3:] + rng.normal(0.0, s, (n, 3))
        block = replace(block, imu=ImuObservations(np.arange(n), ang, np.full((n, 3), s)))
    return replace(block, settings=settings), truth
