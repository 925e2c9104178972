"""Writing a Block as a Bundler v0.3 file (bundle.out, list.txt) or a VisualSFM NVM_V3 file
(model.nvm): the inverses of io/bundler.py and io/nvm.py (conventions there).

Both formats are pixels from the principal point: the image coordinates go out as (x - x0) /
p, so that a camera with a principal point keeps its geometry (the image centre is lost);
p is the width of the camera's pixel (block/pixels.pixel_sizes: the reader's pixel frame,
else the pixel size the block states, else `pixel_mm`, the nominal 1 µm the readers use).
Every point goes out as a tie point with its coordinates (control and check roles have no
place in either format), colours grey; the keypoint index of an
observation is its number among its photo's observations.  Each writer returns what it had
to drop or approximate, in words; a camera model the format cannot hold is a ValueError.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.camera import lens
from baarda.block.photo_block import Block
from baarda.block.pixels import pixel_sizes
from baarda.block.rotation import pose_of_eo
from baarda.io.colmap import matrix_to_qvec
from baarda.io.image_sigma import PIXEL_MM
from baarda.output.atomic import write_text
from baarda.output.block_checks import checked_block

GREY = "128 128 128"
FLIP = np.array([1.0, -1.0, -1.0])


def _pixel(block: Block, pixel_mm: float) -> np.ndarray:
    """The pixel size [mm] of every camera: its width (pixels.pixel_sizes)."""
    return pixel_sizes(block.cameras, pixel_mm)[:, 0]


def _views(block: Block, pixel: np.ndarray, y_sign: float):
    """Per point (in block order) the rows 'photo key x y' in pixels from the principal
    point; keys numbered per photo."""
    im = block.image
    cam = block.photos.camera[im.photo]
    px = pixel[cam]
    xy = (im.xy_mm - block.cameras.principal_point_mm[cam]) / px[:, None]
    key = np.empty(len(im.photo), np.int64)
    by_photo = np.argsort(im.photo, kind="stable")
    starts = np.searchsorted(im.photo[by_photo], im.photo[by_photo], side="left")
    key[by_photo] = np.arange(len(by_photo)) - starts
    order = np.argsort(im.point, kind="stable")
    bounds = np.searchsorted(im.point[order], np.arange(len(block.points.ids) + 1))
    used = np.flatnonzero(np.diff(bounds) > 0)
    rows = [f"{p} {k} {x!r} {y!r}" for p, k, x, y in zip(
        im.photo[order].tolist(), key[order].tolist(), xy[order, 0].tolist(),
        (y_sign * xy[order, 1]).tolist(), strict=True)]
    return used, bounds, rows


def write_bundler(block: Block, folder: str | Path, pixel_mm: float = PIXEL_MM) -> list[str]:
    """bundle.out and list.txt of `block` in `folder` (each atomically); the notes on what
    was dropped.  Cameras: ``none`` or ``brown_forward`` with k1, k2 only (Bundler's model);
    a ``brown`` camera with k1 only (NVM's) goes out with k1 = -k1 c^2, the first-order
    inverse, noted."""
    notes = checked_block(block, coordinates=True, roles=True, principal_point=True)
    folder = Path(folder)
    pixel = _pixel(block, pixel_mm)
    out = ["# Bundle file v0.3", ""]
    approx = []
    for i in range(len(block.photos)):
        ci = int(block.photos.camera[i])
        kind, coef = lens(block.cameras, ci)
        c = float(block.cameras.focal_mm[ci])
        if kind == "none" or (kind in ("brown_forward", "brown") and not np.any(coef)):
            k1 = k2 = 0.0
        elif kind == "brown_forward" and not np.any(coef[2:]):
            k1, k2 = float(coef[0]), float(coef[1])
        elif kind == "brown" and not np.any(coef[1:]):
            k1, k2 = -float(coef[0]) * c * c, 0.0
            approx.append(block.cameras.ids[ci])
        else:
            raise ValueError(f"camera {block.cameras.ids[ci]}: model {kind} with "
                             f"{coef.tolist()} has no Bundler equivalent (f, k1, k2 on "
                             "normalised coordinates)")
        r, t = pose_of_eo(block.photos.eo[i])
        rb, tb = FLIP[:, None] * r, FLIP * t  # Bundler's camera frame: y up, looking down -z
        out.append(f"{float(c / pixel[ci])!r} {k1!r} {k2!r}")
        out += [" ".join(repr(float(v)) for v in row) for row in rb]
        out.append(" ".join(repr(float(v)) for v in tb))
    if approx:
        notes.append(f"camera(s) {', '.join(sorted(set(approx)))}: NVM's radial term on the "
                     "measured point written as Bundler's k1 = -r (first order)")
    used, bounds, rows = _views(block, pixel, 1.0)
    xyz = block.points.xyz
    for j in used:
        out.append(" ".join(repr(float(v)) for v in xyz[j]))
        out.append(GREY)
        out.append(f"{bounds[j + 1] - bounds[j]} " + " ".join(rows[bounds[j]:bounds[j + 1]]))
    out[1] = f"{len(block.photos)} {len(used)}"
    folder.mkdir(parents=True, exist_ok=True)
    write_text(folder / "bundle.out", "\n".join(out) + "\n")
    write_text(folder / "list.txt", "\n".join(block.photos.ids) + "\n")
    return notes + ["Bundler: no principal point, colours grey, point ids renumbered"]


def write_nvm(block: Block, folder: str | Path, pixel_mm: float = PIXEL_MM,
              name: str = "model.nvm") -> list[str]:
    """`folder`/model.nvm of `block` (atomically); the notes on what was dropped.  Cameras:
    ``none`` or ``brown`` with k1 only (VisualSFM's one radial term on the measured point, r =
    k1 c^2); a ``brown_forward`` camera with k1 only (Bundler's, COLMAP's) goes out with r =
    -k1, the first-order inverse, noted; photo ids are the image names."""
    notes = checked_block(block, coordinates=True, roles=True, principal_point=True)
    folder = Path(folder)
    pixel = _pixel(block, pixel_mm)
    bad = [p for p in block.photos.ids if not p or any(ch.isspace() for ch in p)]
    if bad:
        raise ValueError(f"photo id '{bad[0]}': NVM image names have no blanks")
    out = ["NVM_V3", "", str(len(block.photos))]
    approx = []
    for i, pid in enumerate(block.photos.ids):
        ci = int(block.photos.camera[i])
        kind, coef = lens(block.cameras, ci)
        c = float(block.cameras.focal_mm[ci])
        if kind == "none" or (kind in ("brown_forward", "brown") and not np.any(coef)):
            r = 0.0
        elif kind == "brown" and not np.any(coef[1:]):
            r = float(coef[0]) * c * c
        elif kind == "brown_forward" and not np.any(coef[1:]):
            r = -float(coef[0])
            approx.append(block.cameras.ids[ci])
        else:
            raise ValueError(f"camera {block.cameras.ids[ci]}: model {kind} with "
                             f"{coef.tolist()} has no NVM equivalent (one radial term)")
        rot, _ = pose_of_eo(block.photos.eo[i])
        q = matrix_to_qvec(rot)
        x0 = block.photos.eo[i, :3]
        out.append(f"{pid} {float(c / pixel[ci])!r} " + " ".join(repr(float(v)) for v in q)
                   + " " + " ".join(repr(float(v)) for v in x0) + f" {r!r} 0")
    if approx:
        notes.append(f"camera(s) {', '.join(sorted(set(approx)))}: a forward k1 written as "
                     "NVM's r = -k1 on the measured point (first order)")
    used, bounds, rows = _views(block, pixel, -1.0)
    xyz = block.points.xyz
    out += ["", str(len(used))]
    out += [" ".join(repr(float(v)) for v in xyz[j]) + f" {GREY} {bounds[j + 1] - bounds[j]} "
            + " ".join(rows[bounds[j]:bounds[j + 1]]) for j in used]
    out += ["", "0"]
    folder.mkdir(parents=True, exist_ok=True)
    write_text(folder / name, "\n".join(out) + "\n")
    return notes + ["NVM: no principal point, one radial term, colours grey, point ids "
                    "renumbered"]
