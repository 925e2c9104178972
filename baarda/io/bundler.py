"""Bundler v0.3 (`bundle.out` with `list.txt` beside it; written by Bundler, Metashape,
RealityCapture, VisualSFM and COLMAP's exporter).

    # Bundle file v0.3
    <num_cameras> <num_points>
    per camera:  f k1 k2 / R (3 lines) / t
    per point:   X Y Z / R G B / n  (camera key x y) * n

Projection (Bundler's documentation): P = R X + t, p = -P.xy / P.z, x = f (1 + k1 |p|^2 +
k2 |p|^4) p, in pixels with the origin at the image centre, x right, y up; the camera looks
down -z.  That is baarda's camera frame, so R_b = R^T, X0 = -R^T t; c = f p with a nominal
pixel size p (`--pixel-mm`, default 1 µm); lens model ``brown_forward`` (k1, k2) on
normalised coordinates, no principal point (Bundler has none: at the image centre).  Images
that share f, k1 and k2 share a camera; f, k1, k2 are the parameters Bundler estimates.  A
camera of all zeros is an image Bundler did not reconstruct: left out with a note.  list.txt
names the images (first word of each line); without it the images are numbered.  Colours
and keypoint indices are not kept (a Block has none).
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
from baarda.block.rotation import angles_from_matrix, not_a_rotation
from baarda.errors import ProjectError
from baarda.io.records import check_pixel_options, finite_numbers
from baarda.io.text_files import first_line_starts, read_lines, require_file

HEADER = "# Bundle file v0.3"
ROTATION_TOLERANCE = 1e-4  # |R R^T - I| of a rotation written with 6 digits or more


def bundle_file(path: Path) -> Path:
    """The bundle file of `path`: itself, or a folder's bundle.out."""
    return path / "bundle.out" if path.is_dir() else path


def is_bundler(path: str | Path) -> bool:
    """A file (or a folder's bundle.out) whose first line is '# Bundle file v0.x'."""
    return first_line_starts(bundle_file(Path(path)), b"# Bundle file v")


class _Lines:
    """The lines of a file, read one after another; errors name the file and the line."""

    def __init__(self, path: Path, lines: list[str], start: int = 0) -> None:
        self.path, self.lines, self.k = str(path), lines, start

    def error(self, msg: str, field: str | None = None, line: int | None = None) -> ProjectError:
        return ProjectError(self.path, msg, self.k if line is None else line, field)

    def numbers(self, n: int | None, what: str) -> np.ndarray:
        """The next line's numbers (exactly n unless None)."""
        if self.k >= len(self.lines):
            raise ProjectError(self.path, f"the file ends early: {what} expected (a truncated "
                               "file)", len(self.lines) + 1)
        tokens = self.lines[self.k].split()
        self.k += 1
        if n is not None and len(tokens) != n:
            raise self.error(f"{n} numbers expected ({what}), found {len(tokens)}", what)
        return finite_numbers(tokens, self.path, self.k, what)


def check_rotation(r: np.ndarray, where: _Lines, line: int, what: str) -> None:
    """ProjectError unless `r` is a rotation (orthonormal, determinant +1)."""
    why = not_a_rotation(r, ROTATION_TOLERANCE)
    if why is not None:
        raise where.error(f"{what} is {why}", "R", line)


def once_per_image(photo: np.ndarray, point: np.ndarray, key: np.ndarray, n_points: int,
                   notes: list[str], what: str, keys: str) -> np.ndarray:
    """The observations to keep (indices, in file order): a point seen twice in one image
    keeps its lowest key, as COLMAP's reader keeps its first keypoint (a note says how many
    were left out)."""
    pair = photo * n_points + point
    order = np.lexsort((key, pair))
    _, first = np.unique(pair[order], return_index=True)
    sel = np.sort(order[first])
    if len(sel) < len(pair):
        notes.append(f"{len(pair) - len(sel)} repeated {what}(s) of a point in one image left "
                     f"out (the lowest {keys} index kept, as COLMAP's reader does)")
    return sel


def read_list(path: Path, n: int) -> tuple[list[str] | None, str | None]:
    """The image names of list.txt beside the bundle file (None: no list.txt) and a note."""
    lst = path.parent / "list.txt"
    if not lst.is_file():
        return None, "Bundler: no list.txt beside the bundle file: the images are numbered " \
            "0.. in the bundle file's order"
    lines = [s for s in read_lines(lst)]
    names = [s.split()[0] for s in lines if s.strip()]
    if len(names) != n:
        raise ProjectError(str(lst), f"{len(names)} image names, but the bundle file has "
                           f"{n} cameras (one line per camera expected)", len(lines))
    return names, None


def read_bundler(path: str | Path, pixel_mm: float = 0.001, sigma_px: float = 1.0) -> Block:
    """A Block of a Bundler v0.3 file (conventions in the module docstring)."""
    check_pixel_options(pixel_mm, sigma_px)
    p = bundle_file(Path(path))
    require_file(p)
    lines = read_lines(p)
    if not lines or not lines[0].startswith("# Bundle file v"):
        raise ProjectError(str(p), f"first line must be '{HEADER}'", 1)
    if not lines[0].startswith(HEADER):
        raise ProjectError(str(p), f"'{lines[0].strip()}': only Bundler v0.3 is read", 1)
    rd = _Lines(p, lines, 1)
    counts = rd.numbers(2, "num_cameras num_points")
    if np.any(counts != np.round(counts)) or np.any(counts < 0):
        raise rd.error("num_cameras num_points must be counts", "num_cameras num_points")
    nc, npt = (int(v) for v in counts)
    if len(lines) < 2 + 5 * nc + 3 * npt:
        raise ProjectError(str(p), f"the file ends early: {nc} cameras and {npt} points "
                           f"need {2 + 5 * nc + 3 * npt} lines, the file has {len(lines)} "
                           "(a truncated file)", len(lines))
    fk = np.empty((nc, 3))
    rot = np.empty((nc, 3, 3))
    t = np.empty((nc, 3))
    for i in range(nc):
        first = rd.k + 1
        fk[i] = rd.numbers(3, "f k1 k2")
        rot[i] = [rd.numbers(3, "R") for _ in range(3)]
        t[i] = rd.numbers(3, "t")
        if fk[i, 0] != 0 or np.any(rot[i]):
            check_rotation(rot[i], rd, first + 1, f"camera {i}: R")
            if fk[i, 0] <= 0:
                raise rd.error(f"camera {i}: focal length must be positive", "f", first)
    xyz = np.empty((npt, 3))
    views, view_line = [], np.empty(npt, np.int64)
    for j in range(npt):
        xyz[j] = rd.numbers(3, "position")
        rd.numbers(3, "color")
        view_line[j] = rd.k + 1
        v = rd.numbers(None, "view list")
        n = int(v[0]) if len(v) else -1
        if not len(v) or v[0] != n or n < 0 or len(v) != 1 + 4 * n:
            raise rd.error(f"point {j}: a view list 'n (camera key x y) * n' expected"
                           + (f"; it announces {n} views, {len(v) - 1} values follow "
                              f"({4 * n} expected)" if len(v) and n >= 0 else ""), "view list")
        views.append(v[1:].reshape(n, 4))
    if rd.k < len(lines) and any(s.strip() for s in lines[rd.k:]):
        raise ProjectError(str(p), f"data after the last of the {npt} points the header "
                           "announces", rd.k + 1)
    obs = np.concatenate(views) if views else np.empty((0, 4))
    obs_point = np.repeat(np.arange(npt), [len(v) for v in views])
    cam = obs[:, 0]
    made = (fk[:, 0] != 0) | rot.any(axis=(1, 2))
    bad = np.flatnonzero((cam != np.round(cam)) | (cam < 0) | (cam >= nc))
    bad = bad if len(bad) else np.flatnonzero(~made[np.clip(cam, 0, nc - 1).astype(int)])
    if len(bad):
        j = int(obs_point[bad[0]])
        c = cam[bad[0]]
        raise ProjectError(str(p), f"point {j}: view on camera {c:g}, which "
                           + ("does not exist" if not 0 <= c < nc else "Bundler did not "
                              "reconstruct (all zeros)") + f" (cameras 0..{nc - 1})",
                           int(view_line[j]), "view list")
    names, note = read_list(p, nc)
    notes = [] if note is None else [note]
    return _block(p, names, fk, rot, t, made, xyz, obs_point, obs, pixel_mm, sigma_px, notes)


def _block(p: Path, names, fk, rot, t, made, xyz, obs_point, obs, pixel_mm, sigma_px,
           notes) -> Block:
    nc = len(fk)
    keep = np.flatnonzero(made)
    if len(keep) < nc:
        notes.append(f"Bundler: {nc - len(keep)} camera(s) of all zeros (images Bundler did "
                     "not reconstruct) left out")
    ids = [names[i] if names else str(i) for i in keep]
    files = [names[i] for i in keep] if names else None
    stems = [Path(s).stem for s in ids]
    if len(set(stems)) == len(stems):
        ids = stems
    if len(set(ids)) < len(ids):
        raise ProjectError(str(p.parent / "list.txt"), "image names repeat: each image once")
    groups, cam_of = np.unique(fk[keep], axis=0, return_inverse=True)
    cam_of = cam_of.ravel()
    m = len(groups)
    cameras = Cameras([str(k + 1) for k in range(m)], groups[:, 0] * pixel_mm,
                      np.zeros((m, 2)), np.full(m, "brown_forward", dtype=object),
                      np.column_stack([groups[:, 1:3], np.zeros((m, 3))]), None,
                      pixel_frame=centred(m, pixel_mm))
    rt = np.swapaxes(rot[keep], 1, 2)
    x0 = -np.einsum("nij,nj->ni", rt, t[keep])
    photos = Photos(ids, cam_of, np.full(len(keep), "", dtype=object),
                    np.column_stack([x0, angles_from_matrix(rt)]), files)
    index = np.full(nc, -1)
    index[keep] = np.arange(len(keep))
    photo = index[obs[:, 0].astype(np.int64)]
    sel = once_per_image(photo, obs_point, obs[:, 1], len(xyz), notes, "view", "key")
    image = ImagePoints(photo[sel], obs_point[sel], obs[sel, 2:4] * pixel_mm,
                        np.full(len(sel), sigma_px * pixel_mm))
    npt = len(xyz)
    points = GroundPoints([str(j) for j in range(npt)], xyz, np.full((npt, 3), np.nan),
                          np.full(npt, "tie", dtype=object))
    notes.insert(0, f"Bundler v0.3: nominal pixel size {pixel_mm:g} mm (1 px = "
                 f"{pixel_mm * 1e3:g} µm), image origin at the image centre (Bundler has no "
                 "principal point), y up; f, k1, k2 per camera (Bundler's radial model); "
                 "colours and keypoint indices not kept")
    settings = Settings(name=p.parent.name or p.stem, angle_unit="rad",
                        sigma_image_um=sigma_px * pixel_mm * 1e3, datum="free",
                        calibration_free=(("c", "k1", "k2"),) * m)
    return Block(settings, cameras, photos, image, points, source=str(p), notes=notes)


def detect(path: Path) -> bool:
    return is_bundler(path)


def read(path: Path, request) -> Block:
    """The registry's entry (io/formats.py)."""
    from baarda.io.image_sigma import PIXEL_MM, SIGMA_PX

    return read_bundler(path, PIXEL_MM if request.pixel_mm is None else request.pixel_mm,
                        SIGMA_PX if request.sigma_px is None else request.sigma_px)
