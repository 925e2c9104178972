"""Bundle Adjustment in the Large (BAL) problem files (text, optionally .bz2).

    <num_cameras> <num_points> <num_observations>
    <camera_index> <point_index> <x> <y>            one line per observation (0-based)
    <camera parameters>  9 per camera: Rodrigues vector r, translation t, f, k1, k2
    <point coordinates>  3 per point

Projection (BAL): P = R(r) X + t, p = -P.xy / P.z, x = f (1 + k1 |p|^2 + k2 |p|^4) p, in
pixels with the origin at the image centre, +x right, +y up; the camera looks down -z.

Conversion to a Block: R(r) maps world to camera and BAL's camera frame is baarda's (x
right, y up, viewing along -z), so R_b = R(r)^T, X0 = -R(r)^T t; c = f p and the pixels
become mm with a nominal pixel size p (`pixel_mm`, default 0.001 mm: 1 px = 1 µm, so
residuals in µm read as pixels); lens model ``brown_forward`` with (k1, k2, 0, 0, 0) per
camera (the BAL radial model, held fixed); image sigma 1 px unless given.  Each BAL camera
is a camera of its own (per-camera focal length and distortion).
"""

from __future__ import annotations

import bz2
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from baarda.block.camera import INPUT_CALIBRATION
from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.block.rotation import (
    MAX_ANGLE,
    angles_from_matrix,
    rodrigues,
    rotation_matrix,
    rotation_vector,
)
from baarda.errors import ProjectError
from baarda.io.records import check_pixel_options, finite_numbers
from baarda.io.text_files import is_number, require_file, split_lines


@dataclass
class BalProblem:
    cameras: np.ndarray  # (n, 9) r (3), t (3), f, k1, k2
    points: np.ndarray  # (m, 3)
    obs_camera: np.ndarray  # (k,) int
    obs_point: np.ndarray  # (k,) int
    obs_xy: np.ndarray  # (k, 2) pixels


HEADER_LIMIT = 256  # bytes of the first line
BOM = b"\xef\xbb\xbf"  # a UTF-8 byte-order mark (docs/formats.md: always accepted)
BYTES_PER_VALUE = 64  # a value with its separator is never longer in a real file


def _header(line: bytes, path: str) -> tuple[int, int, int]:
    head = line.split()
    if len(head) != 3 or not all(h.isdigit() for h in head):
        raise ProjectError(path, "first line must be: num_cameras num_points num_observations",
                           1)
    nc, npt, nobs = (int(h) for h in head)
    if nc < 1 or npt < 1 or nobs < 1:
        raise ProjectError(path, "counts must be positive", 1)
    return nc, npt, nobs


def _read_at_most(f, limit: int, chunk: int = 1 << 20) -> bytes:
    """Up to `limit` bytes of a stream, read in chunks (memory grows with what is there)."""
    parts, size = [], 0
    while size < limit:
        part = f.read(min(chunk, limit - size))
        if not part:
            break
        parts.append(part)
        size += len(part)
    return b"".join(parts)


def _too_much(path: str, head: bytes, counts: tuple[int, int, int]) -> ProjectError:
    """The error for a file with more data than its header announces: the line where the
    announced values end and more follow, else the line where the limit was reached."""
    nc, npt, nobs = counts
    need = 9 * nc + 3 * npt
    lines = head.split(b"\n")
    for i, line in enumerate(lines[nobs:-1], start=nobs + 2):
        need -= len(line.split())
        if need < 0:
            return ProjectError(path, f"values after the last point ({-need} too many on this "
                                "line; the header announces "
                                f"{nc} cameras, {npt} points, {nobs} observations)", i)
    return ProjectError(path, f"more data than the header's counts ({nc} cameras, {npt} "
                        f"points, {nobs} observations) allow", len(lines) + 1)


def _read_lines(path: Path) -> tuple[tuple[int, int, int], list[str]]:
    """The header's counts and the lines of a BAL file, read as a stream: no more than the
    counts allow is decompressed or read (BYTES_PER_VALUE per announced value)."""
    sp = str(path)
    require_file(path)
    opener = bz2.open if path.suffix == ".bz2" else open
    try:
        with opener(path, "rb") as f:
            first = f.readline(HEADER_LIMIT).removeprefix(BOM)  # a BOM is accepted
            if not first:
                raise ProjectError(sp, "empty file", 1)
            nc, npt, nobs = _header(first, sp)
            limit = (4 * nobs + 9 * nc + 3 * npt) * BYTES_PER_VALUE + 4096
            body = _read_at_most(f, limit + 1)
    except EOFError:
        raise ProjectError(sp, "the bzip2 data end early (a truncated .bz2 file)") from None
    except OSError as e:
        raise ProjectError(sp, f"not a valid bzip2 file ({e})" if opener is bz2.open else
                           f"cannot be read ({e.strerror or e})") from None
    if len(body) > limit:
        raise _too_much(sp, body[:limit], (nc, npt, nobs))
    try:
        text = (first + body).decode("ascii")
    except UnicodeDecodeError as e:
        data = first + body
        raise ProjectError(sp, f"not a text file (byte 0x{data[e.start]:02x})",
                           data.count(b"\n", 0, e.start) + 1) from None
    return (nc, npt, nobs), split_lines(text)


def is_bal(path: str | Path) -> bool:
    """A .bz2, .bal or .txt file whose first line is three counts."""
    p = Path(path)
    if not p.is_file() or p.suffix not in (".bz2", ".bal", ".txt"):
        return False
    try:
        with bz2.open(p, "rb") if p.suffix == ".bz2" else open(p, "rb") as f:
            head = f.readline(HEADER_LIMIT).removeprefix(BOM).split()
    except (OSError, EOFError):
        return False
    return len(head) == 3 and all(h.isdigit() for h in head)


def read_bal(path: str | Path) -> BalProblem:
    """Read a BAL problem; ProjectError with the line of the first malformed value."""
    path = Path(path)
    sp = str(path)
    (nc, npt, nobs), lines = _read_lines(path)
    if len(lines) < 1 + nobs:
        raise ProjectError(sp, f"{nobs} observation lines announced, file has "
                           f"{len(lines) - 1} lines", len(lines))
    obs_lines = lines[1:1 + nobs]
    parts = [s.split() for s in obs_lines]
    widths = np.fromiter((len(p) for p in parts), dtype=np.int64, count=nobs)
    bad = np.flatnonzero(widths != 4)
    if len(bad):
        raise ProjectError(sp, "observation line needs camera_index point_index x y",
                           int(bad[0]) + 2)
    flat = [t for p in parts for t in p]
    try:
        tab = np.array(flat, dtype=float).reshape(nobs, 4)
    except ValueError:
        for i, p in enumerate(parts):
            finite_numbers(p, sp, i + 2, "observation")
        raise
    if not np.isfinite(tab).all():
        i = int(np.flatnonzero(~np.isfinite(tab).all(axis=1))[0])
        raise ProjectError(sp, "not a finite number", i + 2, "observation")
    cam, pt = tab[:, 0], tab[:, 1]
    bad = np.flatnonzero((cam != np.round(cam)) | (cam < 0) | (cam >= nc))
    if len(bad):
        raise ProjectError(sp, f"camera index {parts[bad[0]][0]} not in 0..{nc - 1}",
                           int(bad[0]) + 2, "camera_index")
    bad = np.flatnonzero((pt != np.round(pt)) | (pt < 0) | (pt >= npt))
    if len(bad):
        raise ProjectError(sp, f"point index {parts[bad[0]][1]} not in 0..{npt - 1}",
                           int(bad[0]) + 2, "point_index")
    # parameters: any layout, one value per line in the published files
    rest = lines[1 + nobs:]
    counts = np.fromiter((len(s.split()) for s in rest), dtype=np.int64, count=len(rest))
    need = 9 * nc + 3 * npt
    if counts.sum() < need:
        raise ProjectError(sp, f"{need} parameter values needed (9 per camera, 3 per point), "
                           f"found {int(counts.sum())}", len(lines))
    if counts.sum() > need:
        extra_line = int(np.searchsorted(np.cumsum(counts), need, side="right")) + 2 + nobs
        raise ProjectError(sp, f"values after the last point ({int(counts.sum()) - need} "
                           "too many)", extra_line)
    tokens = " ".join(rest).split()
    try:
        vals = np.array(tokens, dtype=float)
    except ValueError:
        k = next(i for i, t in enumerate(tokens) if not is_number(t))
        line = int(np.searchsorted(np.cumsum(counts), k, side="right")) + 2 + nobs
        raise ProjectError(sp, f"'{tokens[k]}' is not a number", line,
                           "camera" if k < 9 * nc else "point") from None
    if not np.isfinite(vals).all():
        k = int(np.flatnonzero(~np.isfinite(vals))[0])
        line = int(np.searchsorted(np.cumsum(counts), k, side="right")) + 2 + nobs
        raise ProjectError(sp, "not a finite number", line, "camera" if k < 9 * nc else "point")
    cams = vals[:9 * nc].reshape(nc, 9)
    with np.errstate(over="ignore"):
        angle = np.linalg.norm(cams[:, :3], axis=1)
    bad = np.flatnonzero(~(angle <= MAX_ANGLE))
    if len(bad):
        line = int(np.searchsorted(np.cumsum(counts), 9 * bad[0], side="right")) + 2 + nobs
        raise ProjectError(sp, f"camera {bad[0]}: a rotation vector of {angle[bad[0]]:.3g} rad "
                           f"(more than {MAX_ANGLE:g} rad is no rotation a program writes)",
                           line, "r")
    bad = np.flatnonzero(cams[:, 6] <= 0)
    if len(bad):
        line = int(np.searchsorted(np.cumsum(counts), 9 * bad[0] + 6, side="right")) + 2 + nobs
        raise ProjectError(sp, f"camera {bad[0]}: focal length must be positive", line, "f")
    return BalProblem(cams, vals[9 * nc:].reshape(npt, 3), cam.astype(np.int64),
                      pt.astype(np.int64), tab[:, 2:4].copy())


def bal_to_block(problem: BalProblem, pixel_mm: float = 0.001, sigma_px: float = 1.0,
                 name: str = "bal", source: str = "", calibrate: bool = True) -> Block:
    """A Block of a BAL problem (conventions in the module docstring); calibrate: f, k1, k2
    of every camera are unknowns, as the BAL problems intend (False: held at the file's)."""
    check_pixel_options(pixel_mm, sigma_px)
    cams = problem.cameras
    n = len(cams)
    r = rodrigues(cams[:, :3])  # world -> camera
    rt = np.swapaxes(r, 1, 2)
    x0 = -np.einsum("nij,nj->ni", rt, cams[:, 3:6])
    eo = np.column_stack([x0, angles_from_matrix(rt)])
    ids = [str(i) for i in range(n)]
    dist = np.column_stack([cams[:, 7], cams[:, 8], np.zeros((n, 3))])
    kinds = np.full(n, "brown_forward", dtype=object)
    cameras = Cameras(ids, cams[:, 6] * pixel_mm, np.zeros((n, 2)), kinds, dist, None)
    photos = Photos(ids, np.arange(n), np.full(n, "", dtype=object), eo)
    key = problem.obs_camera * len(problem.points) + problem.obs_point
    _, first = np.unique(key, return_index=True)
    keep = np.sort(first)
    notes = [f"BAL problem: nominal pixel size {pixel_mm:g} mm (1 px = {pixel_mm * 1e3:g} µm)",
             INPUT_CALIBRATION + "the focal length and the radial distortion (k1, k2) of "
             "every camera " + ("estimated, as the BAL problems intend" if calibrate
                                else "held fixed")]
    if len(keep) < len(key):
        notes.append(f"{len(key) - len(keep)} repeated observation(s) of a point in one image "
                     "left out (first kept)")
    image = ImagePoints(problem.obs_camera[keep], problem.obs_point[keep],
                        problem.obs_xy[keep] * pixel_mm,
                        np.full(len(keep), sigma_px * pixel_mm))
    m = len(problem.points)
    points = GroundPoints([str(j) for j in range(m)], problem.points.copy(),
                          np.full((m, 3), np.nan), np.full(m, "tie", dtype=object))
    settings = Settings(name=name, angle_unit="rad", sigma_image_um=sigma_px * pixel_mm * 1e3,
                        datum="free", calibration_free=(("c", "k1", "k2"),) * n
                        if calibrate else None)
    return Block(settings, cameras, photos, image, points, source=source, notes=notes)


def bal_with_block(problem: BalProblem, eo: np.ndarray, xyz: np.ndarray,
                   cameras=None, pixel_mm: float = 0.001) -> BalProblem:
    """A copy of `problem` with new orientations (EO per camera) and points (NaN = keep),
    and with `cameras` (baarda Cameras, e.g. self-calibrated) their f, k1, k2."""
    cams = problem.cameras.copy()
    if cameras is not None:
        from baarda.block.camera import coefficients

        cams[:, 6] = np.asarray(cameras.focal_mm) / pixel_mm
        cams[:, 7:9] = [coefficients(cameras, i)[:2] for i in range(len(cams))]
    for i in range(len(cams)):
        rb = rotation_matrix(eo[i, 3], eo[i, 4], eo[i, 5])
        r = rb.T
        cams[i, :3] = rotation_vector(r)
        cams[i, 3:6] = -r @ eo[i, :3]
    pts = np.where(np.isfinite(xyz), xyz, problem.points)
    return BalProblem(cams, pts, problem.obs_camera.copy(), problem.obs_point.copy(),
                      problem.obs_xy.copy())


def read_bal_block(path: str | Path, **kw) -> Block:
    path = Path(path)
    name = path.name.split(".")[0]
    return bal_to_block(read_bal(path), name=kw.pop("name", name), source=str(path), **kw)
