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
    marked points "N id x y sx sy" [pixels]; blank line; features (ignored); blank line.
    An export whose last line is not blank ends inside a section: refused as cut short.

Read as DBAT's loadpm reads it (conversions stated in the notes of the block):

* one camera for every photo: the export's default camera (line 4); the photo blocks repeat
  it rounded to 3 decimals (a note names photos whose camera lines differ beyond that);
* pixels (origin upper-left, y down) -> mm with origin at the image centre, y up:
  x = (x_px - w/2) W/w, y = (h/2 - y_px) H/h, W, H the format size, w, h the image size of
  line 2 (an export without it is an error that says so, unless the pixel size is given:
  w = W / pixel_mm);
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
* marks of ids that are neither control nor object points are dropped (a note names them);
* the control section holds the coordinates and precisions that PhotoModeler lists for its
  control points (after its adjustment; a precision <= 0 is fixed control); they become
  control points with those sigmas, unless a control file replaces them (--control,
  block/control.py), as DBAT's own runs of these exports do;
* text: UTF-8, or cp1252 (PhotoModeler on Windows) with a note when it is not UTF-8.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.control import INPUT_CONTROL
from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.errors import ProjectError
from baarda.io.records import first_appearance, parse_number
from baarda.io.text_files import ENCODING, decode_text, file_bytes, file_head, is_utf8, split_lines


def is_photomodeler_export(path: str | Path) -> bool:
    if Path(path).suffix.lower() != ".txt":
        return False
    return file_head(path, 256, line=True).strip().lower().startswith(b"bundle soln")


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


def _lines(path: str | Path, encoding: str) -> tuple[list[str], list[str]]:
    """The lines of an export and notes: an export that is not UTF-8 (PhotoModeler on
    Windows writes cp1252) is read as cp1252 when no other encoding was named."""
    data = file_bytes(path)
    if is_utf8(encoding):
        try:
            return split_lines(decode_text(data, str(path), encoding)), []
        except ProjectError as e:
            try:
                text = data.decode("cp1252")
            except UnicodeDecodeError:
                raise e from None
            return split_lines(text), [f"{Path(path).name} is not UTF-8 ({e.detail.split(' (')[0]}"
                                       f" on line {e.line}): read as cp1252, the encoding of "
                                       "PhotoModeler on Windows (--encoding names another)"]
    return split_lines(decode_text(data, str(path), encoding)), []


def _check_marking_precisions(sxy: np.ndarray, s_px: np.ndarray, lines: list[int],
                              path: str) -> None:
    """Refuse the first mark (in file order) whose sx or sy (px) is negative, or whose sx
    is 0 while the default of line 3 is not positive, naming its line and column."""
    bad = (sxy < 0) | np.column_stack([s_px <= 0, np.zeros(len(s_px), dtype=bool)])
    rows = np.flatnonzero(bad.any(axis=1))
    if len(rows):
        r = int(rows[0])
        c = int(np.argmax(bad[r]))
        said = (f"marking precision {sxy[r, c]:g} px is negative" if sxy[r, c] < 0 else
                "marking precision 0 px and the default of line 3 is not positive")
        raise ProjectError(path, said, lines[r], ("sx", "sy")[c])


def read_photomodeler(path: str | Path, encoding: str = ENCODING, *,
                      pixel_mm: float | None = None, sigma_px: float | None = None) -> Block:
    """Read a PhotoModeler export into a Block (see the module docstring).

    pixel_mm: the pixel size [mm] of an export whose line 2 lacks the image size (the
    image size is then the format size / pixel_mm); sigma_px: the image sigma [px] of
    every mark instead of the export's."""
    spath = str(path)
    lines, notes = _lines(path, encoding)
    if len(lines) < 6 or not lines[0].strip().lower().startswith("bundle soln"):
        raise ProjectError(spath, "not a PhotoModeler export (first line 'Bundle Soln')", 1)
    if lines[-1].strip():
        raise ProjectError(spath, "the export ends inside a section (PhotoModeler ends each "
                           "section with a blank line): the file is cut short", len(lines))
    head = _nums(lines[1], spath, 2, "tolerance line", at_least=2)
    def_std = _nums(lines[2], spath, 3, "default standard deviations", at_least=1)
    cam = np.array(_nums(lines[3], spath, 4, "default camera", 10))
    c, xp, yp, fw, fh = cam[:5]
    if not (c > 0 and fw > 0 and fh > 0):
        raise ProjectError(spath, "default camera: camera constant and format size must be "
                           "positive", 4)
    if len(head) >= 4:
        if pixel_mm is not None:
            raise ProjectError("command line", f"--pixel-mm does not apply to {Path(path).name}"
                               f": its line 2 gives the image size ({head[2]:g} x {head[3]:g} "
                               "px), from which the pixel size follows")
        iw, ih = head[2], head[3]
        if iw <= 0 or ih <= 0:
            raise ProjectError(spath, "image size must be positive", 2)
    elif pixel_mm is not None:
        iw, ih = fw / pixel_mm, fh / pixel_mm
        notes.append(f"image size {iw:.6g} x {ih:.6g} px from the format {fw:g} x {fh:g} mm "
                     f"and the pixel size {pixel_mm:g} mm (given; line 2 has none)")
    else:
        raise ProjectError(spath, "line 2 gives no image width and height in pixels (the "
                           "export was written without them); they convert the marks from "
                           "pixels to mm: add them after the tolerance and iterations "
                           "('0.0005 20 WIDTH HEIGHT'), or give the pixel size with "
                           "--pixel-mm", 2)

    photos: list[tuple[str, np.ndarray]] = []
    i, differ = 5, []
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
        if np.any(np.abs(np.array(inner[1:]) - cam) > 5.01e-4 + 1e-9 * np.abs(cam)):
            differ.append(n)
        photos.append((name, np.array(outer[1:])))
        i += 6
    if not photos:
        raise ProjectError(spath, "no photo blocks after the header", 6)
    i += 1
    ctrl, ctrl_lines, i = _section(lines, i, spath, 7, "control point")
    objs, _, i = _section(lines, i, spath, 7, "object point")
    marks, mark_lines, i = _section(lines, i, spath, 6, "marked point")
    if not len(marks):
        raise ProjectError(spath, "no marked points (expected after the control and object "
                           "point sections, each ended by a blank line)", min(i, len(lines)))

    # one camera: the export's default camera (line 4), as DBAT reads it; the photo lines
    # repeat it rounded to 3 decimals
    px, py = fw / iw, fh / ih
    coef = cam[5:10].copy()
    cameras = Cameras(["1"], np.array([c]), np.array([[xp - fw / 2, fh / 2 - yp]]),
                      np.array(["brown_backward" if coef.any() else "none"], dtype=object),
                      coef[None, :])
    if differ:
        notes.append(f"the camera lines of {len(differ)} photo(s) (e.g. photo {differ[0]}) "
                     "differ from the default camera (line 4) by more than their rounding; "
                     "as DBAT, every photo takes the default camera")

    names = [Path(p[0].replace("\\", "/")).stem for p in photos]
    if len(set(names)) != len(names):
        names = [str(k) for k in range(len(photos))]
    outer = np.array([p[1] for p in photos])
    eo = np.column_stack([outer[:, :3], np.radians(outer[:, [5, 4, 3]])])
    photo_obj = Photos(names, np.zeros(len(names), np.int64),
                       np.full(len(names), "", dtype=object), eo)

    # points: control first, then object points; marks of other ids are dropped (DBAT)
    ids, index = first_appearance(_pid(v) for v in list(ctrl[:, 0]) + list(objs[:, 0]))
    k = len(ids)
    xyz = np.full((k, 3), np.nan)
    sig = np.full((k, 3), np.nan)
    role = np.full(k, "tie", dtype=object)
    for row in objs:
        xyz[index[_pid(row[0])]] = row[1:4]
    for row in ctrl:
        j = index[_pid(row[0])]
        xyz[j], sig[j], role[j] = row[1:4], np.maximum(row[4:7], 0.0), "control"
    fixed = (ctrl[:, 4:7] <= 0).any(axis=1)
    if fixed.any():
        notes.append(f"{int(fixed.sum())} control point(s) with precision <= 0: fixed "
                     "(PhotoModeler writes a negative precision for fixed control)")

    bad = np.flatnonzero(~((marks[:, 0] >= 0) & (marks[:, 0] < len(photos)) &
                           (marks[:, 0] == np.round(marks[:, 0]))))
    if len(bad):
        raise ProjectError(spath, f"unknown photo number {marks[bad[0], 0]:g}",
                           mark_lines[bad[0]], "photo")
    mark_ids = [_pid(v) for v in marks[:, 1]]
    known = np.array([m in index for m in mark_ids], dtype=bool)
    if not known.all():
        lost = sorted(set(np.asarray(mark_ids, dtype=object)[~known]), key=mark_ids.index)
        if not known.any():
            raise ProjectError(spath, "no marked point is an object or control point of the "
                               "export (the marks refer to other ids)", mark_lines[0], "id")
        notes.append(f"{int((~known).sum())} mark(s) of {len(lost)} point(s) that are not in "
                     "the object point list dropped, as DBAT does: " + ", ".join(lost[:10])
                     + (", ..." if len(lost) > 10 else ""))
        marks = marks[known]
        mark_lines = [n for n, ok in zip(mark_lines, known, strict=True) if ok]
        mark_ids = [m for m, ok in zip(mark_ids, known, strict=True) if ok]
    photo = marks[:, 0].astype(np.int64)
    point = np.array([index[m] for m in mark_ids], dtype=np.int64)
    xy = np.column_stack([(marks[:, 2] - iw / 2) * px, (ih / 2 - marks[:, 3]) * py])
    s_px = np.where(marks[:, 4] > 0, marks[:, 4], def_std[0])
    _check_marking_precisions(marks[:, 4:6], s_px, mark_lines, spath)
    if sigma_px is not None:
        s_px = np.full(len(marks), float(sigma_px))
        notes.append(f"image sigma {sigma_px:g} px for every mark (given)")
    key = photo * k + point
    if len(np.unique(key)) != len(key):
        order = np.argsort(key, kind="stable")
        d = order[np.flatnonzero(np.diff(key[order]) == 0)[0] + 1]
        raise ProjectError(spath, f"point {ids[point[d]]} marked twice on photo {photo[d]}",
                           mark_lines[d], "id")
    image = ImagePoints(photo, point, xy, s_px * py)
    notes = [f"PhotoModeler export {Path(path).name}: pixel size {px:.6g} x {py:.6g} mm; "
             "image origin moved to the image centre, y up; K and P as given (backward "
             "model); the default camera (line 4)", *notes]
    if len(ctrl):
        notes.append(INPUT_CONTROL + "the coordinates and precisions that PhotoModeler lists "
                     "for its control points, its adjusted values and posterior precisions "
                     "(not the surveyed control: --control FILE replaces them, as in DBAT's "
                     "runs)")
    settings = Settings(name=lines[0].strip()[len("Bundle Soln"):].strip() or Path(path).stem,
                        angle_unit="deg", sigma_image_um=float(
                            (def_std[0] if sigma_px is None else sigma_px) * py * 1e3))
    points = GroundPoints(ids, xyz, sig, role)
    return Block(settings, cameras, photo_obj, image, points, source=spath, notes=notes)


def _pid(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))
