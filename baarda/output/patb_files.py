"""Writing a Block as PAT-B files (`block.im`, `.con`, `.ori`, `.at`, `.pro`): the inverse of
io/patb.py (layout there).  Numbers are written as Python's shortest exact form, so that the
files read back give the same observations and orientations.  PAT-B holds no lens
distortion: a camera with a lens model other than zero terms is a ValueError; the image
coordinates go out from the principal point (the image centre is not kept).  Each writer
returns what it had to drop, in words.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block
from baarda.block.rotation import rotation_matrix
from baarda.output.atomic import write_text
from baarda.output.block_checks import checked_block


def _f(v: float) -> str:
    return repr(float(v))


def write_patb(block: Block, folder: str | Path, name: str = "block") -> list[str]:
    """`folder`/name.im, .con, .ori, .at, .pro of `block` (each atomically); the notes on
    what was dropped."""
    notes = checked_block(block, lens=False, ids=True, strips=True)
    folder = Path(folder)
    cams, im, pts = block.cameras, block.image, block.points
    if np.any(cams.principal_point_mm != 0):
        notes.append("principal point: the image coordinates are written from it (PAT-B has "
                     "none; the image centre is not kept)")
    s = block.settings
    default = s.sigma_image_um * 1e-3
    xy = im.xy_mm - cams.principal_point_mm[block.photos.camera[im.photo]]
    sxy = im.sigma_xy_mm
    own = (sxy is not None) or bool(np.any(im.sigma_mm != default))
    out = []
    order = np.argsort(im.photo, kind="stable")
    bounds = np.searchsorted(im.photo[order], np.arange(len(block.photos) + 1))
    for i, pid in enumerate(block.photos.ids):
        out.append(f"{pid} {_f(cams.focal_mm[block.photos.camera[i]])}")
        for k in order[bounds[i]:bounds[i + 1]]:
            row = f"{pts.ids[im.point[k]]} {_f(xy[k, 0])} {_f(xy[k, 1])}"
            if sxy is not None:
                row += f" {_f(sxy[k, 0])} {_f(sxy[k, 1])}"
            elif own:
                row += f" {_f(im.sigma_mm[k])}"
            out.append(row)
        out.append("-99")
    out.append("-99")
    ori = []
    for i, pid in enumerate(block.photos.ids):
        eo = block.photos.eo[i]
        ori.append(f"{pid} " + " ".join(_f(v) for v in eo[:3]))
        ori += [" ".join(_f(v) for v in row) for row in rotation_matrix(*eo[3:])]
    ori.append("-99")
    used = np.unique(im.point)
    con, at = [], []
    for j in used:
        role, v, sig = pts.role[j], pts.xyz[j], pts.sigma[j]
        if role == "check":
            con.append(f"{pts.ids[j]} " + " ".join(_f(x) for x in v) + " 0 "
                       + " ".join(_f(x) for x in np.where(np.isfinite(sig), sig, 0.0)))
        elif role in ("control", "fixed"):
            given = np.isfinite(sig)
            code = 3 if given.all() else 1 if given[:2].all() and not given[2] else \
                2 if given[2] and not given[:2].any() else None
            if code is None:
                raise ValueError(f"point {pts.ids[j]}: control in {given.tolist()} (X, Y, Z): "
                                 "PAT-B holds X, Y, Z, planimetric or height control")
            vv = np.where(np.isfinite(v), v, 0.0)
            con.append(f"{pts.ids[j]} " + " ".join(_f(x) for x in vv) + f" {code} "
                       + " ".join(_f(x) for x in np.where(given, sig, 0.0)))
        elif np.isfinite(v).all():
            at.append(f"{pts.ids[j]} " + " ".join(_f(x) for x in v))
    con.append("-99")
    at.append("-99")
    pro = [f"project {s.name.split()[0] if s.name.split() else name}",
           f"sigma_image_um {_f(s.sigma_image_um)}",
           "sigma_control_m " + " ".join(_f(v) for v in s.sigma_control_m), "-99"]
    folder.mkdir(parents=True, exist_ok=True)
    for suffix, lines in ((".im", out), (".ori", ori), (".con", con), (".at", at),
                          (".pro", pro)):
        write_text(folder / f"{name}{suffix}", "\n".join(lines) + "\n")
    return notes + ["PAT-B: camera constant per photo, no lens distortion, no principal "
                    "point, no camera ids (photos with one c share a camera)"]
