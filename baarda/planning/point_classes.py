"""Gruen's (1980) point and observation classes of image observations.

A ray is a photo that measures the point; a photo that measures it twice (in two stereo
models: "twin rays") counts as one ray and its observations are *inner* rays (I), all other
observations are *outer* rays (O).  Classes by the number of rays: 2, 3 and 4/9 (four or
more; Gruen's blocks have at most nine) and by the point: control (prefix C) or not.

    R2(x), R2(y)                 2-ray points (only outer rays)
    RO3(x), RO3(y), RI3(x,y)     3-ray points, outer and inner rays
    RO4/9(x,y), RI4/9(x,y)       points with 4 or more rays
    CRO4/9(x,y), CRI4/9(x,y)     control points with 4 or more rays

A control point is any point with a controlled coordinate (full, planimetric or height
control); `partial_as_control=False` counts only full (XYZ) control points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.block.photo_block import Block


@dataclass
class RowClasses:
    """Classes of the rows of block.image (one row = x and y of one measurement)."""

    rays: np.ndarray  # (m,) distinct photos measuring the row's point
    inner: np.ndarray  # (m,) bool: the photo measures this point more than once
    control: np.ndarray  # (m,) bool: the point counts as control
    label: np.ndarray  # (m,) object: class name, e.g. 'RO4/9'

    def component_labels(self) -> tuple[np.ndarray, np.ndarray]:
        """(label, component) for the 2m flat components x0, y0, x1, y1, ..."""
        return np.repeat(self.label, 2), np.tile(np.array(["x", "y"], dtype=object),
                                                 len(self.label))


def ray_counts(block: Block) -> tuple[np.ndarray, np.ndarray]:
    """Distinct photos per point (k,) and, per image row, whether it is a twin ray (m,)."""
    im = block.image
    n_ph = max(len(block.photos), 1)
    key = im.point.astype(np.int64) * n_ph + im.photo
    uniq, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    rays = np.bincount(uniq // n_ph, minlength=len(block.points))
    return rays, counts[inv] > 1


def points_per_photo(block: Block) -> np.ndarray:
    """Distinct points measured on each photo, (n_photos,)."""
    n_ph = max(len(block.photos), 1)
    key = np.unique(block.image.point.astype(np.int64) * n_ph + block.image.photo)
    return np.bincount(key % n_ph, minlength=len(block.photos))


def class_name(rays: int, inner: bool, control: bool) -> str:
    """Gruen's class name for one observation (rays counted with twins once)."""
    c = "C" if control else ""
    if rays <= 1:
        return f"{c}R1"
    if rays == 2:
        return f"{c}R2"
    return f"{c}R{'I' if inner else 'O'}{'3' if rays == 3 else '4/9'}"


def control_points(block: Block, partial_as_control: bool = True) -> np.ndarray:
    """(k,) bool: points that count as control (full XYZ; or any coordinate)."""
    ctl = block.points.controlled
    return np.any(ctl, axis=1) if partial_as_control else np.all(ctl, axis=1)


def classify(block: Block, partial_as_control: bool = True) -> RowClasses:
    """Gruen's class of every image row of `block`."""
    rays, inner = ray_counts(block)
    ctrl = control_points(block, partial_as_control)
    im = block.image
    r, c = rays[im.point], ctrl[im.point]
    names = np.array([class_name(int(a), bool(b), bool(d)) for a, b, d in
                      zip(r, inner, c, strict=True)], dtype=object)
    return RowClasses(r, inner, c, names)


def half_coverage_photos(block: Block, fraction: float = 0.6) -> np.ndarray:
    """(n_photos,) bool: photos whose points span a bounding box (in the image) of less than
    `fraction` of the 90th percentile over the photos (perimeter photos with half coverage)."""
    im = block.image
    n = len(block.photos)
    lo = np.full((n, 2), np.inf)
    hi = np.full((n, 2), -np.inf)
    np.minimum.at(lo, im.photo, im.xy_mm)
    np.maximum.at(hi, im.photo, im.xy_mm)
    area = np.prod(np.clip(hi - lo, 0, None), axis=1)
    used = np.isfinite(area) & (np.bincount(im.photo, minlength=n) > 0)
    if not used.any():
        return np.zeros(n, bool)
    ref = np.percentile(area[used], 90)
    return used & (area < fraction * ref)
