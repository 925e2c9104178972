"""VisualSFM NVM_V3 (`*.nvm`; VisualSFM, COLMAP, Meshroom exports).

    NVM_V3 [FixedK fx cx fy cy]
    <num_cameras>
    per camera:  name f qw qx qy qz Cx Cy Cz r 0
    <num_points>
    per point:   X Y Z R G B n  (image feature x y) * n
    ... further models (num_cameras, cameras, num_points, points); 0 cameras ends the list

VisualSFM's conventions (its documentation, ccwu.me/vsfm/doc.html#nvm): the quaternion
(w, x, y, z) rotates world to camera (camera x right, y down, looking along +z), C is the
projection centre; measurements x, y are pixels relative to the image centre (x right, y
down); the radial distortion r applies to the measured point m: undistorted = m (1 + r
|m|^2 / f^2) (r normalised by f, PBA's "measurement distortion").  COLMAP's exporter writes
r = -k of its SIMPLE_RADIAL and measurements from the image corner, not the centre
(colmap/colmap issue 946): such a file is not VisualSFM's.

Conversion to a Block: R_b = R^T diag(1, -1, -1) (baarda's camera frame has y up, looking
down -z), X0 = C; c = f p with a nominal pixel size p (`--pixel-mm`, default 1 µm); image
coordinates (x, -y) p; the distortion is a backward model on the measured point: ``brown``
with k1 = r / c^2 [mm^-2] (``none`` where r = 0).  Images with the same f and r share a
camera; f and r are what VisualSFM estimates.  The first model is read (`model=K`, 0-based,
another), with a note naming how many there are.  Colours, feature indices and the
FixedK line's principal point are not kept.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import (
    Block,
    Cameras,
    GroundPoints,
    ImagePoints,
    Photos,
    Settings,
)
from baarda.block.pixels import centred
from baarda.block.rotation import FLIP, angles_from_matrix, quaternion_matrix
from baarda.errors import ProjectError
from baarda.io.bundler import once_per_image
from baarda.io.records import check_pixel_options, finite_numbers
from baarda.io.text_files import first_line_starts, read_lines, require_file

QUATERNION_TOLERANCE = 1e-4  # | |q| - 1 | of a quaternion written with 6 digits or more


def is_nvm(path: str | Path) -> bool:
    """A file whose first line starts with NVM_V3."""
    return first_line_starts(Path(path), b"NVM_V3")


class _Tokens:
    """The non-blank lines of the file after the header, read line by line."""

    def __init__(self, path: Path, lines: list[str]) -> None:
        self.path = str(path)
        self.rows = [(i + 1, s.split()) for i, s in enumerate(lines) if i > 0 and s.strip()]
        self.k = 0
        self.last = len(lines)

    def next(self, what: str) -> tuple[int, list[str]]:
        if self.k >= len(self.rows):
            raise ProjectError(self.path, f"the file ends early: {what} expected (a truncated "
                               "file)", self.last + 1)
        row = self.rows[self.k]
        self.k += 1
        return row

    def enough(self, n: int, what: str) -> None:
        """ProjectError unless n more lines follow (before anything of size n is made)."""
        left = len(self.rows) - self.k
        if n > left:
            line = self.rows[self.k - 1][0] if self.k else 1
            raise ProjectError(self.path, f"{n} {what} announced, {left} lines follow (a "
                               "truncated file)", line)

    def count(self, what: str) -> tuple[int, int]:
        line, t = self.next(what)
        if len(t) < 1 or not t[0].isdigit():
            raise ProjectError(self.path, f"{what} expected (a count)", line, what)
        return line, int(t[0])


def _model(tk: _Tokens, nc: int):
    """One model's cameras and points (after its camera count)."""
    sp = tk.path
    tk.enough(nc, "cameras")
    names, cams = [], np.empty((nc, 9))
    for i in range(nc):
        line, t = tk.next(f"camera {i}")
        if len(t) != 11:
            raise ProjectError(sp, f"camera {i}: 11 fields expected (name f qw qx qy qz Cx Cy "
                               f"Cz r 0), found {len(t)}", line, "camera")
        names.append(t[0])
        cams[i] = finite_numbers(t[1:10], sp, line, "camera")
        norm = float(np.linalg.norm(cams[i, 1:5]))
        if not abs(norm - 1) <= QUATERNION_TOLERANCE:
            raise ProjectError(sp, f"camera {i} ({t[0]}): the quaternion qw qx qy qz has norm "
                               f"{norm:.9g}, not a rotation (a unit quaternion expected)",
                               line, "quaternion")
        if cams[i, 0] <= 0:
            raise ProjectError(sp, f"camera {i} ({t[0]}): focal length must be positive",
                               line, "f")
    line, npt = tk.count("num_points")
    tk.enough(npt, "points")
    xyz = np.empty((npt, 3))
    views, where = [], np.empty(npt, np.int64)
    for j in range(npt):
        line, t = tk.next(f"point {j}")
        v = finite_numbers(t, sp, line, "point")
        n = int(v[6]) if len(v) >= 7 else -1
        if len(v) < 7 or v[6] != n or n < 0 or len(v) != 7 + 4 * n:
            raise ProjectError(sp, f"point {j}: 'X Y Z R G B n (image feature x y) * n' "
                               "expected" + (f"; it announces {n} measurements, "
                                             f"{len(v) - 7} values follow ({4 * n} expected)"
                                             if n >= 0 else ""), line, "point")
        xyz[j] = v[:3]
        views.append(v[7:].reshape(n, 4))
        where[j] = line
    return names, cams, xyz, views, where


def read_nvm(path: str | Path, pixel_mm: float = 0.001, sigma_px: float = 1.0,
             model: int | None = None) -> Block:
    """A Block of model `model` (0-based; None: the first) of an NVM_V3 file."""
    check_pixel_options(pixel_mm, sigma_px)
    p = Path(path)
    require_file(p)
    lines = read_lines(p)
    if not lines or not lines[0].startswith("NVM_V3"):
        raise ProjectError(str(p), "first line must start with NVM_V3", 1)
    head = lines[0].split()
    if len(head) > 1 and head[1] != "FixedK":
        raise ProjectError(str(p), f"'{lines[0].strip()}': only NVM_V3 (optionally with "
                           "FixedK) is read", 1)
    tk = _Tokens(p, lines)  # a FixedK fx cx fy cy on the header line is not kept
    models = []
    while tk.k < len(tk.rows):
        line, t = tk.rows[tk.k]
        if not (len(t) == 1 and t[0].isdigit()):
            break  # the PLY section or other trailing data
        line, nc = tk.count("num_cameras")
        if nc == 0:
            break
        models.append(_model(tk, nc))
    if not models:
        raise ProjectError(str(p), "no model (a camera count and its cameras expected)", 2)
    k = 0 if model is None else model
    if not 0 <= k < len(models):
        raise ProjectError(str(p), f"model {k} asked for, the file has {len(models)} "
                           f"(0..{len(models) - 1})")
    names, cams, xyz, views, where = models[k]
    notes = []
    if len(models) > 1:
        notes.append(f"NVM: the file has {len(models)} models; model {k} read "
                     f"({len(names)} images; --model K reads another)")
    nc = len(names)
    obs = np.concatenate(views) if views else np.empty((0, 4))
    obs_point = np.repeat(np.arange(len(xyz)), [len(v) for v in views])
    img = obs[:, 0]
    bad = np.flatnonzero((img != np.round(img)) | (img < 0) | (img >= nc))
    if len(bad):
        j = int(obs_point[bad[0]])
        raise ProjectError(str(p), f"point {j}: measurement on image {img[bad[0]]:g}, which "
                           f"does not exist (images 0..{nc - 1})", int(where[j]), "point")
    return _block(p, names, cams, xyz, obs_point, obs, pixel_mm, sigma_px, notes)


def _block(p, names, cams, xyz, obs_point, obs, pixel_mm, sigma_px, notes) -> Block:
    if len(set(names)) < len(names):
        raise ProjectError(str(p), "image names repeat: each image once")
    stems = [Path(s).stem for s in names]
    ids = stems if len(set(stems)) == len(stems) else list(names)
    q = cams[:, 1:5] / np.linalg.norm(cams[:, 1:5], axis=1)[:, None]
    rb = np.swapaxes(quaternion_matrix(q), 1, 2) @ FLIP  # VisualSFM's camera frame: y down
    groups, cam_of = np.unique(cams[:, [0, 8]], axis=0, return_inverse=True)
    cam_of = cam_of.ravel()
    m = len(groups)
    c = groups[:, 0] * pixel_mm
    coef = np.zeros((m, 7))
    coef[:, 0] = groups[:, 1] / c ** 2
    radial = groups[:, 1] != 0
    cameras = Cameras([str(k + 1) for k in range(m)], c, np.zeros((m, 2)),
                      np.where(radial, "brown", "none").astype(object), coef, None,
                      pixel_frame=centred(m, pixel_mm))
    photos = Photos(ids, cam_of, np.full(len(ids), "", dtype=object),
                    np.column_stack([cams[:, 5:8], angles_from_matrix(rb)]), list(names))
    photo = obs[:, 0].astype(np.int64)
    sel = once_per_image(photo, obs_point, obs[:, 1], len(xyz), notes, "measurement", "feature")
    xy = np.column_stack([obs[sel, 2], -obs[sel, 3]]) * pixel_mm
    image = ImagePoints(photo[sel], obs_point[sel], xy, np.full(len(sel), sigma_px * pixel_mm))
    npt = len(xyz)
    points = GroundPoints([str(j) for j in range(npt)], xyz, np.full((npt, 3), np.nan),
                          np.full(npt, "tie", dtype=object))
    notes.insert(0, f"NVM: nominal pixel size {pixel_mm:g} mm (1 px = {pixel_mm * 1e3:g} µm), "
                 "image origin at the image centre (NVM has no principal point), y up; f and "
                 "VisualSFM's one radial term r per camera (k1 = r / c^2 on the measured "
                 "point); colours and feature indices not kept")
    settings = Settings(name=p.stem, angle_unit="rad", sigma_image_um=sigma_px * pixel_mm * 1e3,
                        datum="free",
                        calibration_free=tuple(("c", "k1") if r else ("c",) for r in radial))
    return Block(settings, cameras, photos, image, points, source=str(p), notes=notes)


def detect(path: Path) -> bool:
    return is_nvm(path)


def read(path: Path, request) -> Block:
    """The registry's entry (io/formats.py)."""
    from baarda.io.image_sigma import PIXEL_MM, SIGMA_PX

    return read_nvm(path, PIXEL_MM if request.pixel_mm is None else request.pixel_mm,
                    SIGMA_PX if request.sigma_px is None else request.sigma_px,
                    request.model)
