"""Photo outlines on the ground for the block map.

The block data carry no image format, so the outline drawn is the measured image area of
each camera: the rectangle, symmetric about the principal point, that holds every measured
image point of that camera.  Its corners are intersected with the horizontal plane at the
median height of the adjusted points, with the adjusted orientation and the
omega-phi-kappa convention of baarda.block.rotation.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from baarda.block.rotation import ANGLE_FACTORS, angle_to_rad, rotation_matrix


def image_extent(obs: pd.DataFrame, photos: pd.DataFrame, cameras: dict[str, dict]
                 ) -> dict[str, tuple[float, float]]:
    """Half width and half height (mm) of the measured area of every camera."""
    img = obs.loc[(obs["kind"] == "image") & obs["x_mm"].notna(), ["photo", "x_mm", "y_mm"]]
    cam_of = dict(zip(photos["photo"], photos.get("camera", pd.Series([""] * len(photos))),
                      strict=True))
    cam = pd.Series(img["photo"].to_numpy(object)).map(cam_of).fillna("").to_numpy(object)
    out = {}
    for c, spec in cameras.items():
        sel = cam == c
        if not sel.any():
            continue
        dx = np.abs(img["x_mm"].to_numpy(float)[sel] - spec.get("x0_mm", 0.0))
        dy = np.abs(img["y_mm"].to_numpy(float)[sel] - spec.get("y0_mm", 0.0))
        out[c] = (float(dx.max()), float(dy.max()))
    return out


def footprints(photos: pd.DataFrame, cameras: dict[str, dict], angle_unit: str | None,
               extent: dict[str, tuple[float, float]], ground_z: float
               ) -> dict[str, np.ndarray]:
    """Ground outline (4, 2) in m of every photo whose camera and extent are known."""
    if angle_unit not in ANGLE_FACTORS or "camera" not in photos:
        return {}
    out = {}
    eo_ang = angle_to_rad(photos[["omega", "phi", "kappa"]].to_numpy(float), angle_unit)
    r = rotation_matrix(eo_ang[:, 0], eo_ang[:, 1], eo_ang[:, 2])
    x0 = photos[["X0", "Y0", "Z0"]].to_numpy(float)
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    for i, (pid, cam) in enumerate(zip(photos["photo"], photos["camera"], strict=True)):
        if cam not in cameras or cam not in extent:
            continue
        hx, hy = extent[cam]
        c = float(cameras[cam]["focal_mm"])
        d_cam = np.column_stack([corners[:, 0] * hx, corners[:, 1] * hy, np.full(4, -c)])
        d = d_cam @ r[i].T  # image -> object directions
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (ground_z - x0[i, 2]) / d[:, 2]
        if not np.all(np.isfinite(t) & (t > 0)):
            continue
        out[str(pid)] = x0[i, :2] + t[:, None] * d[:, :2]
    return out


def photo_outlines(res) -> tuple[dict[str, np.ndarray], float]:
    """The ground outlines of a result folder's photos (`footprints` on the measured image
    area, at the median height of the points) and that height (m); ({}, nan) without
    photos, points or cameras."""
    if res.photos is None or res.points is None or not res.cameras or not len(res.points):
        return {}, float("nan")
    ext = image_extent(res.obs, res.photos, res.cameras)
    zg = float(np.nanmedian(res.points["Z"]))
    return footprints(res.photos, res.cameras, res.angle_unit, ext, zg), zg
