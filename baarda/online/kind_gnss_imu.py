"""The on-line bundle's GNSS positions and IMU attitudes as low-rank rows (online/rows.py
takes the other kinds), as the bundle's kind_gnss_imu.py keeps the batch rows of that
kind: each position or attitude three rows (X, Y, Z; omega, phi, kappa), evaluated by
bundle/gnss_imu.py at the photo's current orientation (lever arm; no shifts, drifts or
estimated boresight: the on-line bundle refuses them, online/bundle.refusal)."""

from __future__ import annotations

import numpy as np

from baarda.block.photo_block import (
    Block,
    GnssObservations,
    GroundPoints,
    ImagePoints,
    ImuObservations,
    Photos,
)
from baarda.bundle.gnss_imu import GnssImu
from baarda.kinds import GNSS, IMU
from baarda.online.lowrank import KY, Rows, empty_rows
from baarda.online.measurements import Measurements


def one_photo_each(camera: np.ndarray, eo: np.ndarray) -> Photos:
    """k photos, one per row (camera, orientation eo): the rows of one kind evaluated by the
    bundle's code, each at its own photo's orientation."""
    k = len(camera)
    return Photos([str(i) for i in range(k)], np.asarray(camera, np.int64),
                  np.full(k, "", dtype=object), np.asarray(eo, float))


def extra_rows(block: Block, eo: np.ndarray, gnss_xyz: np.ndarray, gnss_sigma: np.ndarray,
               imu_angles: np.ndarray, imu_sigma: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """Misclosures e (k,) and Jacobians jf (k, 6) of GNSS positions and IMU attitudes of
    photos with orientations eo (one per observation: the GNSS ones, then the IMU ones),
    as bundle/gnss_imu.py has them (lever arm; no shifts, drifts or estimated boresight)."""
    kg, ki = len(gnss_xyz), len(imu_angles)
    photos = one_photo_each(np.zeros(kg + ki, np.int64), eo)
    tmp = Block(block.settings, block.cameras, photos,
                ImagePoints(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2)),
                            np.zeros(0)),
                GroundPoints([], np.zeros((0, 3)), np.zeros((0, 3)),
                             np.zeros(0, dtype=object)),
                gnss=GnssObservations(np.arange(kg), np.asarray(gnss_xyz, float),
                                      np.asarray(gnss_sigma, float)),
                imu=ImuObservations(kg + np.arange(ki), np.asarray(imu_angles, float),
                                    np.asarray(imu_sigma, float)))
    gi = GnssImu(tmp, 0)
    e, jxf, _ = gi.rows(np.asarray(eo, float), np.zeros(0), 0)
    return e, jxf[:, 0, :]


def gnss_imu_rows(f, m: Measurements, group: dict, photo_at
                  ) -> tuple[list[tuple[str, int, int]], Rows]:
    """The rows of a group's GNSS positions and IMU attitudes (online/rows.group_rows):
    their keys (kind, universe index, component) and Rows; `photo_at(i)`: a photo's
    orientation and its new-unknown column (-1: in the factorisation)."""
    ng = f.problem.system.ng
    ext = [(GNSS.name, r, m.g_photo[r]) for r in group[GNSS.name]] + \
        [(IMU.name, r, m.i_photo[r]) for r in group[IMU.name]]
    if not ext:
        return [], empty_rows(ng)
    ph = [photo_at(i) for _, _, i in ext]
    gsel = [r for kind, r, _ in ext if kind == GNSS.name]
    isel = [r for kind, r, _ in ext if kind == IMU.name]
    gnss_sigma = np.array([m.g_sigma[r] for r in gsel]).reshape(-1, 3)
    imu_sigma = np.array([m.i_sigma[r] for r in isel]).reshape(-1, 3)
    e, jf = extra_rows(f.problem.block, np.array([p[0] for p in ph]),
                       np.array([m.g_xyz[r] for r in gsel]).reshape(-1, 3), gnss_sigma,
                       np.array([m.i_angles[r] for r in isel]).reshape(-1, 3), imu_sigma)
    k = 3 * len(ext)
    frame = np.repeat([f.frame_of[i] if c < 0 else -1
                       for (_, _, i), (_, c) in zip(ext, ph, strict=True)], 3)
    pc = np.repeat([c for _, c in ph], 3)
    ycol = np.full((k, KY), -1, np.int64)
    jy = np.zeros((k, KY))
    on = pc >= 0
    ycol[on, :6] = pc[on, None] + np.arange(6)
    jy[on, :6] = jf[on]
    sig = np.concatenate([gnss_sigma.ravel(), imu_sigma.ravel()])
    keys = [(kind, r, c) for kind, r, _ in ext for c in range(3)]
    return keys, Rows(frame, np.where((frame >= 0)[:, None], jf, 0.0), np.full(k, -1),
                      np.zeros((k, 3)), np.zeros((k, ng)), ycol, jy, sig, e)
