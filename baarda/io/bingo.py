"""BINGO image coordinates (Pix4D's `*_tp_bingo.txt`, BINGO's `image.dat`) with Pix4D's
`*_calibrated_camera_parameters.txt` beside them as the cameras and orientations.

BINGO file (Pix4D's article "What is the bingo file generated during Initial Processing"):
per image a header ``image_name CAMERA_W_H`` (Pix4D: the sensor width and height [mm] after
the camera's label, e.g. ``P1060498 H_8.07_6.0525``; BINGO's image.dat: ``photo camera``),
then ``point_id x y`` [mm from the image centre, x right, y up, on the original (distorted)
image], then -99.  GCPs, check points and tie points are all point ids: their ground
coordinates are not in the file (give them with ``--control``).

Pix4D's calibrated camera parameters (the header lines of the file name the fields): per
image ``name width height`` [px], K (3 lines), radial R1 R2 R3, tangential T1 T2, the camera
position t [m] and R (3 lines), with m = K [R | -R t] X: R world to camera with the camera's
y down, looking along +z, K's cx, cy in pixels from the top-left corner.  Becomes: pixel p =
sensor width [mm] / width [px] (the BINGO header's; without one `--pixel-mm`, default 1 µm);
c = fx p; principal point ((cx - W/2) p, (H/2 - cy) p); lens ``brown_forward`` on normalised
coordinates (Pix4D's perspective model, its image frame y up: k1..k3 = R1..R3, baarda's p1 =
T2, p2 = T1, aspect a = fy / fx - 1); images with the same values share a camera; X0 = t,
R_b = R^T diag(1, -1, -1); with Pix4D's `*_offset.xyz` beside them (the camera file is in
the output frame less that offset) X0 = t + offset.  Every calibrated image must have a
BINGO record (a truncated file otherwise) and every BINGO image a calibration.  No public
Pix4D sample with a licence was found (tests/data/bingo_pix4d/README.md): tested against
files written from this layout.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.block.rotation import eo_of_pose, not_a_rotation
from baarda.errors import ProjectError
from baarda.io.image_sigma import PIXEL_MM, SIGMA_PX
from baarda.io.minus99 import Row, data_rows, groups
from baarda.io.records import first_appearance
from baarda.io.text_files import ENCODING, read_lines, whole_lines

CAMERA_FILE = "calibrated_camera_parameters.txt"
ROTATION_TOLERANCE = 1e-4
RECORD = 10  # lines per image in the camera file


def bingo_file(path: str | Path) -> Path:
    """The BINGO file of `path`: itself, or its folder's one `*bingo.txt`."""
    p = Path(path)
    if not p.is_dir():
        return p
    found = sorted(p.glob("*bingo.txt"))
    if len(found) != 1:
        raise ProjectError(str(p), f"{len(found)} '*bingo.txt' files: give the BINGO file"
                           if found else "no '*bingo.txt' file (BINGO image coordinates)")
    return found[0]


def camera_file(bingo: Path) -> Path:
    """Pix4D's calibrated camera parameters beside the BINGO file."""
    found = sorted(bingo.parent.glob(f"*{CAMERA_FILE}"))
    if len(found) != 1:
        raise ProjectError(str(bingo.parent), f"{len(found)} '*_{CAMERA_FILE}' files beside "
                           f"{bingo.name}: one expected (Pix4D's cameras and orientations of "
                           "the BINGO images)")
    return found[0]


def is_bingo(path: str | Path) -> bool:
    """A '*bingo.txt' file, or a folder with one (its content is checked when read, so that
    an empty or cut file is refused naming it, not as an unknown format)."""
    p = Path(path)
    if p.is_dir():
        return len(list(p.glob("*bingo.txt"))) == 1
    return p.name.lower().endswith("bingo.txt") and p.is_file()


def _sensor_mm(path: str, h: Row) -> tuple[float, float] | None:
    """The sensor size [mm] of a Pix4D header's camera token LABEL_W_H (None: no size)."""
    parts = h.tokens[1].split("_")
    if len(parts) < 3:
        return None
    try:
        w, hh = float(parts[-2]), float(parts[-1])
    except ValueError:
        return None
    if not (np.isfinite(w) and np.isfinite(hh) and w > 0 and hh > 0):
        raise ProjectError(path, f"sensor size {parts[-2]} x {parts[-1]} mm: positive numbers "
                           "expected", h.line, "camera")
    return w, hh


def read_cameras(path: Path, encoding: str = ENCODING) -> tuple[list[str], np.ndarray, list[int]]:
    """Pix4D's calibrated camera parameters: names, values (n, 28): W H, K (9), R1..R3,
    T1 T2, t (3), R (9), and the first line of each record."""
    p = str(path)
    lines = whole_lines(path, encoding)
    k = 0
    while k < len(lines):  # the header: lines before the first 'name width height'
        t = lines[k].split()
        if len(t) == 3 and t[1].isdigit() and t[2].isdigit():
            break
        k += 1
    body = [(n + 1, s.split()) for n, s in enumerate(lines) if n >= k and s.strip()]
    if not body:
        raise ProjectError(p, "no image records ('name width height' and 9 lines of K, "
                           "distortion, t and R)", len(lines))
    if len(body) % RECORD:
        raise ProjectError(p, f"{len(body)} record lines: {RECORD} per image expected (a "
                           "truncated file?)", body[-1][0])
    names, values, first = [], np.empty((len(body) // RECORD, 28)), []
    named: set[str] = set()
    sizes = (3, 3, 3, 3, 3, 2, 3, 3, 3, 3)
    fields = ("name width height", "K", "K", "K", "radial distortion",
              "tangential distortion", "camera position t", "R", "R", "R")
    for i in range(len(body) // RECORD):
        rec = body[i * RECORD:(i + 1) * RECORD]
        row = []
        for (line, tokens), n, what in zip(rec, sizes, fields, strict=True):
            if len(tokens) != n:
                raise ProjectError(p, f"{n} fields expected ({what}), found {len(tokens)}",
                                   line, what)
            row.append(Row(line, tokens).numbers(p, 1 if what.startswith("name") else 0,
                                                 ("width", "height") if what.startswith(
                                                     "name") else (what,) * n))
        v = np.concatenate(row)
        head = rec[0][0]
        if v[0] <= 0 or v[1] <= 0 or v[0] != round(v[0]) or v[1] != round(v[1]):
            raise ProjectError(p, "image width and height must be positive whole pixels",
                               head, "width")
        kk = v[2:11].reshape(3, 3)
        if kk[0, 0] <= 0 or kk[1, 1] <= 0 or kk[0, 1] != 0 or np.any(kk[2] != [0, 0, 1]) \
                or kk[1, 0] != 0:
            raise ProjectError(p, f"image {rec[0][1][0]}: K must be [fx 0 cx; 0 fy cy; 0 0 1] "
                               "with fx, fy > 0", head + 1, "K")
        rot = v[19:28].reshape(3, 3)
        why = not_a_rotation(rot, ROTATION_TOLERANCE)
        if why is not None:
            raise ProjectError(p, f"image {rec[0][1][0]}: R is {why}", head + 7, "R")
        if rec[0][1][0] in named:
            raise ProjectError(p, f"image {rec[0][1][0]} twice", head, "name")
        names.append(rec[0][1][0])
        named.add(rec[0][1][0])
        values[i] = v
        first.append(head)
    return names, values, first


def read_offset(folder: Path, encoding: str = ENCODING) -> tuple[np.ndarray, Path] | None:
    """Pix4D's `*_offset.xyz` beside the files (one line X Y Z [m], subtracted from the
    output coordinates in the camera file), and its path; None when there is none."""
    found = sorted(folder.glob("*_offset.xyz"))
    if not found:
        return None
    if len(found) > 1:
        raise ProjectError(str(folder), f"{len(found)} '*_offset.xyz' files: one expected")
    # Pix4D may write its one line without a line end: read_lines, not whole_lines
    rows = [Row(k + 1, t.split()) for k, t in enumerate(read_lines(found[0], encoding))
            if t.strip()]
    if len(rows) != 1 or len(rows[0].tokens) != 3:
        raise ProjectError(str(found[0]), "one line 'X Y Z' expected", rows[0].line if rows
                           else 1, "offset")
    return rows[0].numbers(str(found[0]), 0, ("X", "Y", "Z")), found[0]


def _matcher(names: list[str]) -> Callable[[str], int | None]:
    """The camera-file record of a BINGO image name: the same name, or the only one with
    that stem (None: no such record); the look-ups built once for all images."""
    index: dict[str, int] = {}
    for i, n in enumerate(names):
        index.setdefault(n, i)
    by_stem: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        by_stem.setdefault(Path(n).stem, []).append(i)

    def match(name: str) -> int | None:
        if name in index:
            return index[name]
        found = by_stem.get(name, [])
        return found[0] if len(found) == 1 else None
    return match


def read_bingo(path: str | Path, pixel_mm: float | None = None, sigma_px: float = SIGMA_PX,
               encoding: str = ENCODING) -> Block:
    """A Block of a BINGO file and Pix4D's camera file beside it (module docstring)."""
    bf = bingo_file(path)
    b = str(bf)
    cf = camera_file(bf)
    names, values, first = read_cameras(cf, encoding)
    photo_ids: list[str] = []
    rec_of: list[int] = []
    pixel: list[float] = []
    obs_photo: list[int] = []
    obs_point: list[str] = []
    xy: list[np.ndarray] = []
    match = _matcher(names)
    taken: set[int] = set()
    for g in groups(bf, data_rows(bf, encoding), "image", closing=False):
        h = g.header
        if len(h.tokens) != 2:
            raise ProjectError(b, f"an image header 'name CAMERA' expected, found "
                               f"{len(h.tokens)} field(s)", h.line, "image")
        name = h.tokens[0]
        r = match(name)
        if r is None:
            raise ProjectError(b, f"image {name} is not in {cf.name} ({len(names)} images): "
                               "an unknown image", h.line, "image")
        if r in taken:
            raise ProjectError(b, f"image {name} has two records", h.line, "image")
        size = _sensor_mm(b, h)
        w, hh = values[r, 0], values[r, 1]
        if size is not None:
            p = size[0] / w
            if not np.isclose(size[1] / hh, p, rtol=1e-6):
                raise ProjectError(b, f"image {name}: sensor {size[0]:g} x {size[1]:g} mm and "
                                   f"{w:g} x {hh:g} px give different pixel sizes", h.line,
                                   "camera")
        else:
            p = np.nan
        seen: set[str] = set()
        for row in g.rows:
            if len(row.tokens) != 3:
                raise ProjectError(b, f"image {name}: 'point_id x y' expected, found "
                                   f"{len(row.tokens)} field(s)" + (
                                       " (a -99 missing before an image header?)"
                                       if len(row.tokens) == 2 else ""), row.line, "point")
            if row.tokens[0] in seen:
                raise ProjectError(b, f"point {row.tokens[0]} twice on image {name}",
                                   row.line, "point")
            seen.add(row.tokens[0])
            xy.append(row.numbers(b, 1, ("x", "y")))
            obs_photo.append(len(photo_ids))
            obs_point.append(row.tokens[0])
        photo_ids.append(name)
        rec_of.append(r)
        taken.add(r)
        pixel.append(p)
    missing = sorted(set(range(len(names))) - set(rec_of))
    if missing:
        raise ProjectError(b, f"image {names[missing[0]]} of {cf.name} (line "
                           f"{first[missing[0]]}) has no BINGO record: {len(missing)} of "
                           f"{len(names)} images missing (a truncated file?)")
    notes: list[str] = []
    px = np.array(pixel)
    if np.isnan(px).any():
        nominal = PIXEL_MM if pixel_mm is None else pixel_mm
        px = np.where(np.isnan(px), nominal, px)
        notes.append(f"BINGO: no sensor size in an image header: pixel {nominal:g} mm "
                     "(--pixel-mm)")
    elif pixel_mm is not None:
        raise ProjectError("command line", "--pixel-mm does not apply: the BINGO headers give "
                           "the sensor size")
    v = values[rec_of]
    fx, fy, cx, cy = v[:, 2], v[:, 6], v[:, 4], v[:, 7]
    coef = np.column_stack([v[:, 11:14], v[:, 15], v[:, 14], fy / fx - 1])
    key = np.column_stack([v[:, :11], v[:, 11:16], px])
    groups_, cam_of = np.unique(key, axis=0, return_inverse=True)
    cam_of = cam_of.ravel()
    m = len(groups_)
    first_of = np.array([int(np.flatnonzero(cam_of == k)[0]) for k in range(m)])
    pc = px[first_of]
    focal = fx[first_of] * pc
    pp = np.column_stack([(cx[first_of] - v[first_of, 0] / 2) * pc,
                          (v[first_of, 1] / 2 - cy[first_of]) * pc])
    cc = coef[first_of]
    lens = np.any(cc != 0, axis=1)
    cameras = Cameras([str(k + 1) for k in range(m)], focal, pp,
                      np.where(lens, "brown_forward", "none").astype(object),
                      np.where(lens[:, None], cc, 0.0), None, pc)
    rot = v[:, 19:28].reshape(-1, 3, 3)
    centre = v[:, 16:19]
    offset = read_offset(bf.parent, encoding)
    if offset is not None:
        centre = centre + offset[0]
        notes.append(f"Pix4D: camera positions + the offset {offset[0].tolist()} of "
                     f"{offset[1].name} (Pix4D's camera file is in the offset frame)")
    eo = eo_of_pose(rot, -np.einsum("nij,nj->ni", rot, centre))
    eo[:, :3] = centre
    photos = Photos(photo_ids, cam_of, np.full(len(photo_ids), "", dtype=object), eo)
    point_ids, index = first_appearance(obs_point)
    op = np.array(obs_photo, np.int64)
    image = ImagePoints(op, np.array([index[q] for q in obs_point], np.int64),
                        np.array(xy).reshape(-1, 2), sigma_px * px[op])
    npt = len(point_ids)
    points = GroundPoints(point_ids, np.full((npt, 3), np.nan), np.full((npt, 3), np.nan),
                          np.full(npt, "tie", dtype=object))
    notes.insert(0, f"BINGO + Pix4D ({bf.name}, {cf.name}): image coordinates in mm from "
                 "the image centre; cameras and orientations from Pix4D's file (pixel = "
                 "sensor width / image width); every point a tie point (GCP coordinates are "
                 f"not in BINGO: --control); image sigma {sigma_px:g} px")
    settings = Settings(name=bf.stem, angle_unit="rad",
                        sigma_image_um=float(np.median(sigma_px * px)) * 1e3, datum="free")
    return Block(settings, cameras, photos, image, points, source=b, notes=notes)


def detect(path: Path) -> bool:
    return is_bingo(path)


def read(path: Path, request) -> Block:
    """The registry's entry (io/formats.py)."""
    return read_bingo(path, request.pixel_mm, SIGMA_PX if request.sigma_px is None
                      else request.sigma_px, request.encoding)
