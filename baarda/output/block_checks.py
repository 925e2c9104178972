"""The checks every block writer makes before writing (output/sfm_files.py,
metashape_files.py, block_formats.py, patb_files.py, bingo_files.py), and the notes on what
a format drops that several share.  Each writer asks for what applies to its format."""

from __future__ import annotations

import numpy as np

from baarda.block.camera import lens as camera_lens
from baarda.block.photo_block import Block
from baarda.io.minus99 import is_end


def check_ids(ids: list[str], what: str) -> None:
    """ValueError naming an id a blank-separated -99 format cannot hold."""
    for i in ids:
        if not i or any(ch.isspace() for ch in i) or i.startswith("#"):
            raise ValueError(f"{what} id '{i}': the format's ids have no blanks and do not "
                             "start with '#'")
        if is_end([i]):
            raise ValueError(f"{what} id '{i}' reads as the record end -99")


def checked_block(block: Block, *, lens: bool = True, ids: bool = False,
                  coordinates: bool = False, roles: bool = False,
                  principal_point: bool = False, strips: bool = False) -> list[str]:
    """ValueError for a block a writer cannot write (no photos or image points, a photo
    without an orientation); the notes on what the format drops.  What applies to the
    format: lens: it holds a lens model (else a camera with non-zero terms is a ValueError);
    ids: its ids are blank-separated -99 records (check_ids); coordinates: every observed
    point needs coordinates; roles: control and check points go out as tie points (noted);
    principal_point: it has none, the image coordinates go out from it (noted); strips: it
    has no strips (noted).  GNSS, IMU and distance observations are noted as not written."""
    if not len(block.photos) or not len(block.image.photo):
        raise ValueError("the block has no photos or no image points")
    if not np.isfinite(block.photos.eo).all():
        raise ValueError("every photo needs an orientation (pipeline.with_approximations)")
    used = np.unique(block.image.point)
    if ids:
        check_ids(block.photos.ids, "photo")
        check_ids([block.points.ids[j] for j in used], "point")
    cams = block.cameras
    if not lens:
        for i in range(len(cams)):
            kind, coef = camera_lens(cams, i)
            if kind != "none" and np.any(coef):
                raise ValueError(f"camera {cams.ids[i]}: model {kind} with "
                                 f"{coef.tolist()}: the format holds no lens distortion")
    if coordinates and not np.isfinite(block.points.xyz[used]).all():
        raise ValueError("every observed point needs coordinates "
                         "(pipeline.with_tie_coordinates)")
    notes = []
    tie = block.points.role[used] == "tie"
    if roles and not tie.all():
        notes.append(f"{int(np.sum(~tie))} control/check point(s) written as tie "
                     "points (no control in the format)")
    if principal_point and np.any(cams.principal_point_mm != 0):
        notes.append("principal point: the image coordinates are written from it (the format "
                     "has none; the image centre is not kept)")
    extra = [n for n, v in (("GNSS", block.gnss), ("IMU", block.imu),
                            ("distance", block.distances)) if len(v)]
    if extra:
        notes.append(f"{', '.join(extra)} observations not written (no place in the format)")
    if strips and len(set(block.photos.strip.tolist()) - {""}):
        notes.append("strips not written (no place in the format)")
    return notes
