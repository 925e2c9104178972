"""PhotoModeler "Bundle Soln" export files (the format DBAT's loadpm reads).

Layout (whitespace separated, CRLF or LF):

    line 1  title
    line 2  tolerance, max iterations[, image width, height in pixels]
    line 3  default standard deviations: photo coordinates, control, object points, ...
    line 4  default camera: c, xp, yp, format width, height [mm], K1, K2, K3, P1, P2
    line 5  their standard deviations
    per photo (N = 0-based photo number), 6 lines:
            N file name / N X Y Z kappa phi omega [m, deg] / N their std devs /
            camera-position covariances (often blank) / N camera (as line 4) / N std devs
    blank line; control points "id X Y Z sX sY sZ"; blank line;
    object points "id X Y Z sX sY sZ"; blank line;
    marked points "N id x y sx sy" [pixels]; blank line; features (ignored).

Conversions (stated in the notes of the block):

* pixels (origin upper-left, y down) -> mm with origin at the image centre, y up:
  x = (x_px - w/2) W/w, y = (h/2 - y_px) H/h, W, H the format size;
* principal point xp, yp [mm from the upper-left corner, y down] -> (xp - W/2, H/2 - yp);
* lens distortion: PhotoModeler's K1..K3, P1, P2 are the coefficients of the
  ``brown_backward`` model as they are (ideal = u + delta(u)); DBAT negates them because
  its legacy model 1 subtracts the correction.  Checked in tests/io/test_photomodeler.py by
  reprojecting PhotoModeler's own calibration solution: 0.4 px RMS (limited by the five
  printed decimals of K2) against 27 px with the opposite sign;
* principal point in true mm (for the non-square pixels of the camcal camera the x of pp
  is not rescaled, unlike DBAT's model 3; that fits PhotoModeler's solution best);
* angles kappa, phi, omega in degrees -> omega, phi, kappa; positions are the values of the
  file (PhotoModeler's adjusted EO, used as approximations);
* marking precision sx [pixels]; 0 (SmartPoints) -> the default of line 3;
* the control section holds the coordinates and precisions that PhotoModeler lists for its
  control points (after its adjustment); they become control points with those sigmas.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.errors import ProjectError
from baarda.io.records import ENCODING, first_appearance, parse_number, read_lines


def is_photomodeler_export(path: str | Path) -> bool:
    p = Path(path)
    if not p.is_file() or p.suffix.lower() != ".txt":
        return False
    with open(p, "rb") as f:
        return f.readline(256).strip().lower().startswith(b"bundle soln")


def _nums(line: str, path: str, no: int, what: str, count: int | None = None,
          at_least: int | None = None) -> list[float]:
    parts = line.split()
    if (count is not None and len(parts) != count) or (at_least is not None and
                                                       len(parts) < at_least):
        want = count if count is not None else f"at least {at_least}"
        raise ProjectError(path, f"{what}: expected {want} numbers, found {len(parts)}", no)
    return [parse_number(p, path, no, f"{what} {k + 1}") for k, p in enumerate(parts)]


def _section(lines: list[str], i: int, path: str, width: int, what: str):
    """Rows of `width` numbers from line i up to a blank line; returns (rows, lines, next i)."""
    rows, nos = [], []
    while i < len(lines) and lines[i].strip():
        rows.append(_nums(lines[i], path, i + 1, what, width))
        nos.append(i + 1)
        i += 1
    return np.asarray(rows, float).reshape(-1, width), nos, i + 1


def read_photomodeler(path: str | Path, encoding: str = ENCODING) -> Block:
    """Read a PhotoModeler export into a Block (see the module docstring)."""
    spath = str(path)
    lines = read_lines(path, encoding)
    if len(lines) < 6 or not lines[0].strip().lower().startswith("bundle soln"):
        raise ProjectError(spath, "not a PhotoModeler export (first line 'Bundle Soln')", 1)
    head = _nums(lines[1], spath, 2, "tolerance line", at_least=2)
    if len(head) < 4:
        raise ProjectError(spath, "image width and height (end of line 2) are needed to "
                           "convert pixels to mm", 2)
    iw, ih = head[2], head[3]
    if iw <= 0 or ih <= 0:
        raise ProjectError(spath, "image size must be positive", 2)
    def_std = _nums(lines[2], spath, 3, "default standard deviations", at_least=1)
    _nums(lines[3], spath, 4, "default camera", 10)  # validated; photos carry their own

    photos, i = [], 5
    while i < len(lines) and lines[i].strip():
        parts = lines[i].split(maxsplit=1)
        try:
            n = int(parts[0])
        except ValueError:
            raise ProjectError(spath, f"photo number '{parts[0]}' is not an integer",
                               i + 1) from None
        if n != len(photos):
            raise ProjectError(spath, f"photo number {n}, expected {len(photos)}", i + 1)
        if i + 5 >= len(lines):
            raise ProjectError(spath, "file ends inside a photo block", i + 1)
        name = parts[1].strip() if len(parts) > 1 else str(n)
        outer = _nums(lines[i + 1], spath, i + 2, "photo position/angles", 7)
        inner = _nums(lines[i + 4], spath, i + 5, "photo camera", 11)
        for k, row in ((1, outer), (4, inner)):
            if int(row[0]) != n:
                raise ProjectError(spath, f"line belongs to photo {int(row[0])}, expected {n}",
                                   i + 1 + k)
        photos.append((name, np.array(outer[1:]), np.array(inner[1:])))
        i += 6
    if not photos:
        raise ProjectError(spath, "no photo blocks after the header", 6)
    i += 1
    ctrl, _, i = _section(lines, i, spath, 7, "control point")
    objs, obj_lines, i = _section(lines, i, spath, 7, "object point")
    marks, mark_lines, i = _section(lines, i, spath, 6, "marked point")
    if not len(marks):
        raise ProjectError(spath, "no marked points (expected after the control and object "
                           "point sections, each ended by a blank line)", min(i, len(lines)))

    # cameras: one per distinct set of inner parameters
    inner = np.array([p[2] for p in photos])
    uniq, cam_of = np.unique(inner, axis=0, return_inverse=True)
    cam_of = cam_of.ravel()
    c, xp, yp, fw, fh = (uniq[:, k] for k in range(5))
    if np.any(c <= 0) or np.any(fw <= 0) or np.any(fh <= 0):
        raise ProjectError(spath, "camera constant and format size must be positive")
    px, py = fw / iw, fh / ih
    cameras = Cameras([str(k + 1) for k in range(len(uniq))], c,
                      np.column_stack([xp - fw / 2, fh / 2 - yp]),
                      np.full(len(uniq), "brown_backward", dtype=object), uniq[:, 5:10].copy())
    none = ~np.any(uniq[:, 5:10] != 0, axis=1)
    cameras.model[none] = "none"

    names = [Path(p[0].replace("\\", "/")).stem for p in photos]
    if len(set(names)) != len(names):
        names = [str(k) for k in range(len(photos))]
    outer = np.array([p[1] for p in photos])
    eo = np.column_stack([outer[:, :3], np.radians(outer[:, [5, 4, 3]])])
    photo_obj = Photos(names, cam_of.astype(np.int64), np.full(len(names), "", dtype=object),
                       eo)

    # points: control first, then object points, then marked-only ids
    ids, index = first_appearance(
        _pid(v) for v in list(ctrl[:, 0]) + list(objs[:, 0]) + list(marks[:, 1]))
    k = len(ids)
    xyz = np.full((k, 3), np.nan)
    sig = np.full((k, 3), np.nan)
    role = np.full(k, "tie", dtype=object)
    for row in objs:
        xyz[index[_pid(row[0])]] = row[1:4]
    for row in ctrl:
        j = index[_pid(row[0])]
        xyz[j], sig[j], role[j] = row[1:4], row[4:7], "control"
    bad = np.flatnonzero((role == "control") & ~(sig > 0).all(axis=1))
    if len(bad):
        raise ProjectError(spath, f"control point {ids[bad[0]]}: standard deviations must be "
                           "positive")

    bad = np.flatnonzero(~((marks[:, 0] >= 0) & (marks[:, 0] < len(photos)) &
                           (marks[:, 0] == np.round(marks[:, 0]))))
    if len(bad):
        raise ProjectError(spath, f"unknown photo number {marks[bad[0], 0]:g}",
                           mark_lines[bad[0]], "photo")
    photo = marks[:, 0].astype(np.int64)
    point = np.array([index[_pid(v)] for v in marks[:, 1]], dtype=np.int64)
    cam = cam_of[photo]
    xy = np.column_stack([(marks[:, 2] - iw / 2) * px[cam], (ih / 2 - marks[:, 3]) * py[cam]])
    s_px = np.where(marks[:, 4] > 0, marks[:, 4], def_std[0])
    if np.any(s_px <= 0) or np.any(marks[:, 4:6] < 0):
        raise ProjectError(spath, "marking precision must be positive",
                           mark_lines[int(np.argmin(s_px))], "sx")
    key = photo * k + point
    if len(np.unique(key)) != len(key):
        order = np.argsort(key, kind="stable")
        d = order[np.flatnonzero(np.diff(key[order]) == 0)[0] + 1]
        raise ProjectError(spath, f"point {ids[point[d]]} marked twice on photo {photo[d]}",
                           mark_lines[d], "id")
    image = ImagePoints(photo, point, xy, s_px * py[cam])
    notes = [f"PhotoModeler export {Path(path).name}: pixel size {px[0]:.6g} x {py[0]:.6g} mm; "
             "image origin moved to the image centre, y up; K and P as given (backward model)",
             "control coordinates and sigmas as listed by PhotoModeler (its adjusted values)"]
    settings = Settings(name=lines[0].strip()[len("Bundle Soln"):].strip() or Path(path).stem,
                        angle_unit="deg", sigma_image_um=float(def_std[0] * py[0] * 1e3))
    points = GroundPoints(ids, xyz, sig, role)
    return Block(settings, cameras, photo_obj, image, points, source=spath, notes=notes)


def _pid(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))
