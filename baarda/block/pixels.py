"""Pixels of the original image -> the block's image coordinates [mm].

Pixel coordinates (u, v) here have their origin at the upper-left corner of the image, u to
the right, v down, and the centre of the first pixel at (0, 0) (OpenDroneMap's and
OpenSfM's gcp_list.txt, OpenCV: pixel centres on integers).  A reader states the grid of
each camera (Cameras.image_size_px W, H and Cameras.pixel_xy_mm px, py: the mm of one pixel
as it scaled the image coordinates); every reader's image coordinates have their origin at
the image centre (the point W/2, H/2 of the continuous pixel plane whose corner is 0, 0) with
y up, so

    x = (u + 0.5 - W/2) px,    y = (H/2 - v - 0.5) py.

COLMAP's keypoints put the first pixel's centre at (0.5, 0.5) (hence the + 0.5); Bundler's
and VisualSFM's measurements are relative to the image centre (-W/2 .. W/2).
"""

from __future__ import annotations

import numpy as np

from baarda.block.photo_block import Cameras

CENTRE_OF_FIRST_PIXEL = 0.0  # gcp_list.txt: the first pixel's centre at (0, 0)


def known_grid(cameras: Cameras) -> np.ndarray:
    """(n,) bool: the camera's image size and pixel size are known."""
    if cameras.image_size_px is None or cameras.pixel_xy_mm is None:
        return np.zeros(len(cameras), bool)
    return (np.isfinite(cameras.image_size_px).all(axis=1)
            & np.isfinite(cameras.pixel_xy_mm).all(axis=1))


def _grid(cameras: Cameras, camera: np.ndarray, n: int):
    """(W H (m, 2), px py (m, 2)) of cameras `camera`; NaN where the grid is unknown."""
    camera = np.asarray(camera, np.int64)
    if cameras.image_size_px is None or cameras.pixel_xy_mm is None:
        return np.full((n, 2), np.nan), np.full((n, 2), np.nan)
    return cameras.image_size_px[camera], cameras.pixel_xy_mm[camera]


def pixels_to_mm(cameras: Cameras, camera: np.ndarray, uv: np.ndarray,
                 first_centre: float = CENTRE_OF_FIRST_PIXEL) -> np.ndarray:
    """Image coordinates [mm] (m, 2) of pixels uv (m, 2) on cameras `camera` (m,) (module
    docstring; `first_centre`: the coordinate of the first pixel's centre, 0 or 0.5).  NaN
    where the camera's grid is unknown."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    size, pix = _grid(cameras, camera, len(uv))
    shift = 0.5 - first_centre
    return np.column_stack([(uv[:, 0] + shift - size[:, 0] / 2) * pix[:, 0],
                            (size[:, 1] / 2 - uv[:, 1] - shift) * pix[:, 1]])


def mm_to_pixels(cameras: Cameras, camera: np.ndarray, xy_mm: np.ndarray,
                 first_centre: float = CENTRE_OF_FIRST_PIXEL) -> np.ndarray:
    """The inverse of pixels_to_mm (for writers and tests)."""
    xy_mm = np.asarray(xy_mm, float).reshape(-1, 2)
    size, pix = _grid(cameras, camera, len(xy_mm))
    shift = 0.5 - first_centre
    return np.column_stack([xy_mm[:, 0] / pix[:, 0] + size[:, 0] / 2 - shift,
                            size[:, 1] / 2 - xy_mm[:, 1] / pix[:, 1] - shift])
