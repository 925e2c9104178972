"""Pixels of an image <-> the block's image coordinates [mm], one convention for all.

A reader states how its image coordinates sit on each camera's pixels
(`Cameras.pixel_frame`, (n, 4): c0, r0, pw, ph) and, where it knows it, the image's size
(`Cameras.image_size_px`, (n, 2): W, H [px], NaN unknown).  On the continuous pixel plane
whose origin is the upper-left corner of the upper-left pixel (x to the right, y down, as
Pillow counts; the first pixel's centre at (0.5, 0.5)):

    column = c0 + x / pw,    row = r0 - y / ph,

with (c0, r0) the point of the image coordinates' origin (NaN: the image's centre, W/2 and
H/2; readers that do not know the image's size: Bundler, NVM, COLMAP, OpenSfM, DBAT; the
principal point for MicMac) and pw, ph the width and height of a pixel [mm] as the reader
scaled the image coordinates (COLMAP: p and p fx/fy; DBAT: the sensor's).

Pixel coordinates (u, v) that put the first pixel's centre at `first_centre` are
column - 0.5 + first_centre, row - 0.5 + first_centre: OpenDroneMap's and OpenSfM's
gcp_list.txt and OpenCV put it at (0, 0) (CENTRE_OF_FIRST_PIXEL), so with the origin at the
centre x = (u + 0.5 - W/2) pw, y = (H/2 - v - 0.5) ph; COLMAP's keypoints put it at 0.5.
`baarda review`'s chips (review/chips.py) and `--gcp-list` (block/gcp.py) both use these.
"""

from __future__ import annotations

import numpy as np

from baarda.block.photo_block import Cameras

CENTRE_OF_FIRST_PIXEL = 0.0  # gcp_list.txt: the first pixel's centre at (0, 0)


def centred(n: int, pixel_mm: float) -> np.ndarray:
    """Cameras.pixel_frame of n cameras whose image coordinates have their origin at the
    image's centre, square pixels of pixel_mm."""
    return np.tile([np.nan, np.nan, pixel_mm, pixel_mm], (n, 1))


def known_grid(cameras: Cameras) -> np.ndarray:
    """(n,) bool: the camera's image size and pixel size are known."""
    if cameras.image_size_px is None or cameras.pixel_frame is None:
        return np.zeros(len(cameras), bool)
    pix = np.asarray(cameras.pixel_frame, float)[:, 2:]
    return (np.isfinite(cameras.image_size_px).all(axis=1)
            & np.isfinite(pix).all(axis=1) & (pix > 0).all(axis=1))


def frame_to_pixels(frame: np.ndarray, size: np.ndarray, xy_mm: np.ndarray) -> np.ndarray:
    """(m, 2) column, row on the continuous pixel plane (module docstring) of image
    coordinates xy_mm (m, 2) [mm], by pixel frames (m, 4) c0, r0, pw, ph on images of
    size (m, 2) W, H [px] (used where c0 or r0 is NaN)."""
    frame, size = np.asarray(frame, float), np.asarray(size, float)
    xy_mm = np.asarray(xy_mm, float).reshape(-1, 2)
    origin = np.where(np.isnan(frame[:, :2]), size / 2, frame[:, :2])
    return np.column_stack([origin[:, 0] + xy_mm[:, 0] / frame[:, 2],
                            origin[:, 1] - xy_mm[:, 1] / frame[:, 3]])


def frame_to_mm(frame: np.ndarray, size: np.ndarray, colrow: np.ndarray) -> np.ndarray:
    """The inverse of frame_to_pixels: image coordinates [mm] (m, 2) of column, row."""
    frame, size = np.asarray(frame, float), np.asarray(size, float)
    colrow = np.asarray(colrow, float).reshape(-1, 2)
    origin = np.where(np.isnan(frame[:, :2]), size / 2, frame[:, :2])
    return np.column_stack([(colrow[:, 0] - origin[:, 0]) * frame[:, 2],
                            (origin[:, 1] - colrow[:, 1]) * frame[:, 3]])


def _grid(cameras: Cameras, camera: np.ndarray, n: int):
    """(frame (m, 4), W H (m, 2)) of cameras `camera`; NaN where unknown."""
    camera = np.asarray(camera, np.int64)
    frame = (np.full((n, 4), np.nan) if cameras.pixel_frame is None
             else np.asarray(cameras.pixel_frame, float)[camera])
    size = (np.full((n, 2), np.nan) if cameras.image_size_px is None
            else np.asarray(cameras.image_size_px, float)[camera])
    return frame, size


def pixels_to_mm(cameras: Cameras, camera: np.ndarray, uv: np.ndarray,
                 first_centre: float = CENTRE_OF_FIRST_PIXEL) -> np.ndarray:
    """Image coordinates [mm] (m, 2) of pixels uv (m, 2) on cameras `camera` (m,) (module
    docstring; `first_centre`: the coordinate of the first pixel's centre, 0 or 0.5).  NaN
    where the camera's grid is unknown."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    frame, size = _grid(cameras, camera, len(uv))
    return frame_to_mm(frame, size, uv + (0.5 - first_centre))


def mm_to_pixels(cameras: Cameras, camera: np.ndarray, xy_mm: np.ndarray,
                 first_centre: float = CENTRE_OF_FIRST_PIXEL) -> np.ndarray:
    """The inverse of pixels_to_mm (for writers and tests)."""
    xy_mm = np.asarray(xy_mm, float).reshape(-1, 2)
    frame, size = _grid(cameras, camera, len(xy_mm))
    return frame_to_pixels(frame, size, xy_mm) - (0.5 - first_centre)


def pixel_sizes(cameras: Cameras, default: float) -> np.ndarray:
    """(n, 2) the pixel width and height [mm] of every camera, for the writers: the frame's
    pw, ph where the reader gave them (`Cameras.pixel_frame`), else the pixel size the block
    states (`Cameras.pixel_mm`), else `default` (the nominal pixel of formats in pixels)."""
    n = len(cameras)
    px = (np.full(n, np.nan) if cameras.pixel_mm is None
          else np.asarray(cameras.pixel_mm, float).reshape(n))
    px = np.where(np.isfinite(px) & (px > 0), px, default)
    out = np.column_stack([px, px])
    if cameras.pixel_frame is not None:
        pxy = np.asarray(cameras.pixel_frame, float)[:, 2:]
        ok = np.isfinite(pxy).all(axis=1) & (pxy > 0).all(axis=1)
        out = np.where(ok[:, None], pxy, out)
    return out


def image_sizes(cameras: Cameras, obs_camera: np.ndarray, xy_mm: np.ndarray,
                pixel: np.ndarray) -> np.ndarray:
    """(n, 2) int width, height [px] of every camera's images, for the writers: the block's
    (`Cameras.image_size_px`) where its grid is known (known_grid), else the smallest even
    frame centred on the image coordinates' origin that holds the observations xy_mm (m, 2)
    [mm] of cameras obs_camera (m,), in pixels (n, 2) [mm] (pixel_sizes); 2 x 2 without
    observations."""
    n = len(cameras)
    pixel = np.asarray(pixel, float).reshape(n, 2)
    xy_mm = np.asarray(xy_mm, float).reshape(-1, 2)
    out = np.zeros((n, 2), np.int64)
    known = known_grid(cameras)
    given = np.asarray(cameras.image_size_px if known.any() else np.zeros((n, 2)), float)
    for i in range(n):
        if known[i]:
            out[i] = np.round(given[i])
            continue
        xy = np.abs(xy_mm[obs_camera == i]) / pixel[i]
        ext = np.ceil(xy.max(axis=0)) + 1 if len(xy) else np.ones(2)
        out[i] = 2 * ext
    return out
