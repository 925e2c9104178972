"""Writing a Block as a BINGO file with Pix4D's calibrated camera parameters beside it
(`NAME_tp_bingo.txt`, `NAME_calibrated_camera_parameters.txt`): the inverse of io/bingo.py
(conventions there).  Pixels and image sizes: block/pixels.pixel_sizes and image_sizes (a
camera's image size is the block's where its grid is known, else the smallest even number
of pixels whose frame, centred on the image centre, holds all its image points); the
sensor size in the BINGO header is that size times the camera's pixel (the nominal 1 µm
where the block states none).  Numbers are written as Python's shortest exact form.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.camera import lens
from baarda.block.photo_block import Block
from baarda.block.pixels import image_sizes, pixel_sizes
from baarda.block.rotation import pose_of_eo
from baarda.io.image_sigma import PIXEL_MM
from baarda.output.atomic import write_text
from baarda.output.block_checks import checked_block

HEADER = ["fileName imageWidth imageHeight", "camera matrix K [3x3]",
          "radial distortion [3x1]", "tangential distortion [2x1]",
          "camera position t [3x1]", "camera rotation R [3x3]",
          "camera model m = K [R|-Rt] X", ""]


def _f(v: float) -> str:
    return repr(float(v))


def _lens(block: Block, i: int) -> np.ndarray:
    """R1 R2 R3 T1 T2 and the aspect a of camera i (ValueError for a model Pix4D's
    perspective lens cannot hold)."""
    cams = block.cameras
    kind, coef = lens(cams, i)
    if kind == "none" or not np.any(coef):
        return np.zeros(6)
    if kind != "brown_forward":
        raise ValueError(f"camera {cams.ids[i]}: model {kind} with {coef.tolist()} has no "
                         "Pix4D equivalent (Brown k1..k3, p1, p2 on normalised coordinates)")
    k1, k2, k3, p1, p2, a = coef[:6]
    return np.array([k1, k2, k3, p2, p1, a])


def write_bingo(block: Block, folder: str | Path, name: str = "block") -> list[str]:
    """`folder`/NAME_tp_bingo.txt and NAME_calibrated_camera_parameters.txt (atomically);
    the notes on what was dropped."""
    notes = checked_block(block, lens=True, ids=True, strips=True)
    folder = Path(folder)
    cams, im, pts = block.cameras, block.image, block.points
    pxy = pixel_sizes(cams, PIXEL_MM)
    px = pxy[:, 0]
    lenses = [_lens(block, i) for i in range(len(cams))]
    cam = block.photos.camera
    size = image_sizes(cams, cam[im.photo], im.xy_mm, pxy).astype(float)
    bingo, par = [], list(HEADER)
    order = np.argsort(im.photo, kind="stable")
    bounds = np.searchsorted(im.photo[order], np.arange(len(block.photos) + 1))
    for i, pid in enumerate(block.photos.ids):
        c = int(cam[i])
        w, h = size[c]
        p = px[c]
        bingo.append(f"{pid} C{c + 1}_{_f(w * p)}_{_f(h * p)}")
        for k in order[bounds[i]:bounds[i + 1]]:
            bingo.append(f"{pts.ids[im.point[k]]} {_f(im.xy_mm[k, 0])} {_f(im.xy_mm[k, 1])}")
        bingo.append("-99")
        fx = cams.focal_mm[c] / p
        k1, k2, k3, t1, t2, a = lenses[c]
        cx = w / 2 + cams.principal_point_mm[c, 0] / p
        cy = h / 2 - cams.principal_point_mm[c, 1] / p
        r, _ = pose_of_eo(block.photos.eo[i])
        par += [f"{pid} {int(w)} {int(h)}", f"{_f(fx)} 0 {_f(cx)}",
                f"0 {_f(fx * (1 + a))} {_f(cy)}", "0 0 1", f"{_f(k1)} {_f(k2)} {_f(k3)}",
                f"{_f(t1)} {_f(t2)}", " ".join(_f(v) for v in block.photos.eo[i, :3])]
        par += [" ".join(_f(v) for v in row) for row in r]
    used = np.unique(im.point)
    roles = pts.role[used]
    if np.any(roles != "tie"):
        notes.append(f"{int(np.sum(roles != 'tie'))} control/check point(s): their ground "
                     "coordinates are not in BINGO (give them with --control)")
    notes.append("BINGO: no image sigmas (the reader takes 1 px or --sigma-px), no tie "
                 "coordinates (intersected again), image size from the points' extent")
    folder.mkdir(parents=True, exist_ok=True)
    write_text(folder / f"{name}_tp_bingo.txt", "\n".join(bingo) + "\n")
    write_text(folder / f"{name}_calibrated_camera_parameters.txt", "\n".join(par) + "\n")
    return notes
