"""PAT-B (Inpho/Match-AT's and Metashape's aerial-triangulation exchange): a folder of files
with one stem, or the ``.im`` file of it (its siblings found by its stem, else the only one of
their kind in the folder).  Free format: blank-separated fields (a fixed-format file whose
columns are separated by blanks reads the same); every list ends with a line ``-99``.

* ``.im`` image coordinates [mm, from the principal point, x right, y up]: per photo a
  header ``photo_id c`` (camera constant [mm]), then ``point_id x y [sigma | sx sy]``
  (sigmas [mm], optional), then -99; the file ends with one more -99.
* ``.con`` control: ``point_id X Y Z [code [sX sY sZ]]`` [m], then -99.  code 3 (or none):
  X, Y, Z control; 1: planimetric (X, Y); 2: height (Z); 0: a check point (its sigmas where
  > 0).
* ``.ori`` orientations: per photo ``photo_id X0 Y0 Z0`` [m] and three lines of the
  rotation matrix (image to object, baarda's R = R_x(omega) R_y(phi) R_z(kappa)); then -99.
* ``.at`` adjusted terrain (tie point coordinates): ``point_id X Y Z``, then -99.
* ``.pro`` project (optional): ``key value`` lines: ``project NAME``, ``sigma_image_um S``,
  ``sigma_control_m SX SY SZ``; other keys are noted and not used; then -99.

Photos that share c share a camera (no distortion: PAT-B's image coordinates are corrected
and reduced to the principal point).  No public PAT-B specification or sample file was
found (tests/data/patb/README.md): the layout above is baarda's reading of PAT-B's
published conventions and what `output/patb_files.py` writes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.block.rotation import angles_from_matrix, not_a_rotation
from baarda.errors import ProjectError
from baarda.io.minus99 import Row, data_rows, groups, is_end, rows_to_end
from baarda.io.records import first_appearance
from baarda.io.text_files import ENCODING

SUFFIXES = (".im", ".con", ".ori", ".at", ".pro")
ROTATION_TOLERANCE = 1e-4
DEFAULT_SIGMA_UM = Settings.sigma_image_um  # without a .pro: the image sigma [µm]
DEFAULT_CONTROL_M = Settings.sigma_control_m  # without a .pro: the control sigmas [m]
CODES = {3: (True, True, True), 1: (True, True, False), 2: (False, False, True)}


def files(path: str | Path) -> dict[str, Path]:
    """The PAT-B files of `path` (a folder or its .im): suffix -> path, '.im' always."""
    p = Path(path)
    if p.is_dir():
        ims = sorted(p.glob("*.im"))
        if len(ims) != 1:
            raise ProjectError(str(p), f"{len(ims)} .im files: a PAT-B folder has one "
                               "(give the .im file)" if ims else "no .im file (PAT-B image "
                               "coordinates)")
        p = ims[0]
    out = {".im": p}
    for suffix in SUFFIXES[1:]:
        own = p.with_suffix(suffix)
        if own.is_file():
            out[suffix] = own
            continue
        found = sorted(p.parent.glob(f"*{suffix}"))
        if len(found) == 1 and found[0].is_file():
            out[suffix] = found[0]
    return out


def is_patb(path: str | Path) -> bool:
    """A .im file, or a folder with one .im file (its content is checked when read, so that
    an empty or cut .im is refused naming it, not as an unknown format)."""
    p = Path(path)
    if p.is_dir():
        return len(list(p.glob("*.im"))) == 1
    return p.suffix.lower() == ".im" and p.is_file()


def _read_pro(path: Path, encoding: str, notes: list[str]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    known = {"project": 1, "sigma_image_um": 1, "sigma_control_m": 3}
    for r in rows_to_end(path, data_rows(path, encoding), "project lines"):
        key = r.tokens[0].lower()
        if key in known:
            if len(r.tokens) != 1 + known[key]:
                raise ProjectError(str(path), f"{key}: {known[key]} value(s) expected, found "
                                   f"{len(r.tokens) - 1}", r.line, key)
            if key != "project":
                r.numbers(str(path), 1, (key,) * known[key])
            out[key] = r.tokens[1:]
        else:
            notes.append(f"PAT-B {path.name}, line {r.line}: '{key}' not used")
    return out


def _point_row(path: str, r: Row, photo: str) -> tuple[np.ndarray, np.ndarray | None]:
    n = len(r.tokens)
    if n not in (3, 4, 5):
        raise ProjectError(path, f"photo {photo}: 'point_id x y [sigma | sx sy]' expected, "
                           f"found {n} field(s)" + (" (a -99 missing before a photo header?)"
                                                   if n == 2 else ""), r.line, "point")
    xy = r.numbers(path, 1, ("x", "y"))
    sig = None
    if n > 3:
        sig = r.numbers(path, 3, ("sigma",) if n == 4 else ("sx", "sy"))
        if np.any(sig <= 0):
            raise ProjectError(path, "an image sigma must be positive", r.line, "sigma")
    return xy, sig


def read_patb(path: str | Path, encoding: str = ENCODING) -> Block:
    """A Block of a PAT-B project (conventions in the module docstring)."""
    f = files(path)
    im = f[".im"]
    notes: list[str] = []
    pro = _read_pro(f[".pro"], encoding, notes) if ".pro" in f else {}
    sigma_um = float(pro["sigma_image_um"][0]) if "sigma_image_um" in pro else DEFAULT_SIGMA_UM
    ctrl_sigma = tuple(float(v) for v in pro.get("sigma_control_m", DEFAULT_CONTROL_M))
    ims = str(im)
    photo_ids: list[str] = []
    recorded: set[str] = set()
    focal: list[float] = []
    obs_photo: list[int] = []
    obs_point: list[str] = []
    xy: list[np.ndarray] = []
    sig: list[np.ndarray] = []
    per_axis = False
    for g in groups(im, data_rows(im, encoding), "photo", closing=True):
        h = g.header
        if len(h.tokens) != 2:
            raise ProjectError(ims, f"a photo header 'photo_id c' expected, found "
                               f"{len(h.tokens)} field(s)", h.line, "photo")
        pid = h.tokens[0]
        c = h.numbers(ims, 1, ("c",))[0]
        if c <= 0:
            raise ProjectError(ims, f"photo {pid}: the camera constant must be positive",
                               h.line, "c")
        if pid in recorded:
            raise ProjectError(ims, f"photo {pid} has two records", h.line, "photo")
        recorded.add(pid)
        seen: set[str] = set()
        for r in g.rows:
            v, s = _point_row(ims, r, pid)
            if r.tokens[0] in seen:
                raise ProjectError(ims, f"point {r.tokens[0]} twice on photo {pid}", r.line,
                                   "point")
            seen.add(r.tokens[0])
            obs_photo.append(len(photo_ids))
            obs_point.append(r.tokens[0])
            xy.append(v)
            per_axis |= s is not None and len(s) == 2
            sig.append(np.full(2, np.nan) if s is None else np.resize(s, 2))
        photo_ids.append(pid)
        focal.append(c)
    if not photo_ids:
        raise ProjectError(ims, "no photo records")
    point_ids, index = first_appearance(obs_point)
    npt = len(point_ids)
    xyz = np.full((npt, 3), np.nan)
    sigma = np.full((npt, 3), np.nan)
    role = np.full(npt, "tie", dtype=object)
    if ".con" in f:
        _read_con(f[".con"], encoding, index, xyz, sigma, role, ctrl_sigma, notes)
    if ".at" in f:
        _read_at(f[".at"], encoding, index, xyz, role, notes)
    eo = np.full((len(photo_ids), 6), np.nan)
    if ".ori" in f:
        _read_ori(f[".ori"], encoding, {p: k for k, p in enumerate(photo_ids)}, eo)
    missing = int(np.isnan(eo[:, 0]).sum())
    if missing:
        notes.append(f"PAT-B: {missing} photo(s) without an orientation (.ori): "
                     "approximated")
    cs, cam_of = np.unique(np.array(focal), return_inverse=True)
    m = len(cs)
    cameras = Cameras([str(k + 1) for k in range(m)], cs, np.zeros((m, 2)))
    photos = Photos(photo_ids, cam_of.ravel(), np.full(len(photo_ids), "", dtype=object), eo)
    s = np.array(sig).reshape(-1, 2)
    s = np.where(np.isnan(s), sigma_um * 1e-3, s)
    image = ImagePoints(np.array(obs_photo, np.int64),
                        np.array([index[q] for q in obs_point], np.int64),
                        np.array(xy).reshape(-1, 2),
                        np.sqrt(np.mean(s * s, axis=1)) if per_axis else s[:, 0],
                        sigma_xy_mm=s if per_axis else None)
    used = ", ".join(k for k in SUFFIXES if k in f)
    notes.insert(0, f"PAT-B ({used}): image coordinates in mm from the principal point, "
                 "camera constant per photo (photos with the same c share a camera, no "
                 "distortion)" + ("" if ".pro" in f else f"; no .pro: image sigma "
                                  f"{sigma_um:g} µm"))
    controlled = bool(np.any(role == "control"))
    settings = Settings(name=str(pro.get("project", [im.stem])[0]), angle_unit="gon",
                        sigma_image_um=sigma_um, sigma_control_m=ctrl_sigma,  # type: ignore[arg-type]
                        datum="control" if controlled else "free")
    points = GroundPoints(point_ids, xyz, sigma, role)
    return Block(settings, cameras, photos, image, points, source=str(im), notes=notes)


def _unknown_point(path: Path, r: Row, index: dict[str, int], notes: list[str],
                   what: str) -> int | None:
    k = index.get(r.tokens[0])
    if k is None:
        notes.append(f"PAT-B {path.name}: {what} {r.tokens[0]} (line {r.line}) is measured on "
                     "no photo: not used")
    return k


def _read_con(path: Path, encoding: str, index, xyz, sigma, role, ctrl_sigma, notes) -> None:
    p = str(path)
    seen: set[str] = set()
    for r in rows_to_end(path, data_rows(path, encoding), "control points"):
        n = len(r.tokens)
        if n not in (4, 5, 8):
            raise ProjectError(p, f"'point_id X Y Z [code [sX sY sZ]]' expected, found {n} "
                               "field(s)", r.line, "point")
        v = r.numbers(p, 1, ("X", "Y", "Z"))
        code = 3 if n == 4 else r.numbers(p, 4, ("code",))[0]
        if code not in (0, 1, 2, 3):
            raise ProjectError(p, f"code {r.tokens[4]}: 3 (X, Y, Z), 1 (planimetric), 2 "
                               "(height) or 0 (check point) expected", r.line, "code")
        s = r.numbers(p, 5, ("sX", "sY", "sZ")) if n == 8 else np.array(ctrl_sigma, float)
        if np.any(s < 0):
            raise ProjectError(p, "a standard deviation must not be negative", r.line, "sX")
        if r.tokens[0] in seen:
            raise ProjectError(p, f"point {r.tokens[0]} twice", r.line, "point")
        seen.add(r.tokens[0])
        k = _unknown_point(path, r, index, notes, "control point")
        if k is None:
            continue
        xyz[k] = v
        if code == 0:  # a check point: its sigmas where given (> 0), else none
            role[k] = "check"
            if n == 8:
                sigma[k] = np.where(s > 0, s, np.nan)
            continue
        role[k] = "control"
        sigma[k] = np.where(CODES[int(code)], s, np.nan)


def _read_at(path: Path, encoding: str, index, xyz, role, notes) -> None:
    p = str(path)
    for r in rows_to_end(path, data_rows(path, encoding), "points"):
        if len(r.tokens) != 4:
            raise ProjectError(p, f"'point_id X Y Z' expected, found {len(r.tokens)} "
                               "field(s)", r.line, "point")
        v = r.numbers(p, 1, ("X", "Y", "Z"))
        k = _unknown_point(path, r, index, notes, "point")
        if k is not None and role[k] == "tie":
            xyz[k] = v


def _read_ori(path: Path, encoding: str, photo: dict[str, int], eo: np.ndarray) -> None:
    p = str(path)
    rows = rows_to_end(path, data_rows(path, encoding), "orientations")
    if len(rows) % 4:
        raise ProjectError(p, f"{len(rows)} lines: 4 per photo expected ('photo_id X0 Y0 Z0' "
                           "and three rotation rows; a truncated file?)", rows[-1].line)
    done: set[int] = set()
    for k in range(0, len(rows), 4):
        h = rows[k]
        if len(h.tokens) != 4:
            raise ProjectError(p, f"'photo_id X0 Y0 Z0' expected, found {len(h.tokens)} "
                               "field(s)", h.line, "photo")
        i = photo.get(h.tokens[0])
        if i is None:
            raise ProjectError(p, f"photo {h.tokens[0]} is not one of the .im file's "
                               f"{len(photo)} photos", h.line, "photo")
        if i in done:
            raise ProjectError(p, f"photo {h.tokens[0]} has two orientations", h.line, "photo")
        done.add(i)
        x0 = h.numbers(p, 1, ("X0", "Y0", "Z0"))
        rot = np.empty((3, 3))
        for j in range(3):
            r = rows[k + 1 + j]
            if len(r.tokens) != 3 or is_end(r.tokens):
                raise ProjectError(p, f"photo {h.tokens[0]}: rotation row {j + 1}: 3 numbers "
                                   f"expected, found {len(r.tokens)}", r.line, "R")
            rot[j] = r.numbers(p, 0, (f"R{j + 1}1", f"R{j + 1}2", f"R{j + 1}3"))
        why = not_a_rotation(rot, ROTATION_TOLERANCE)
        if why is not None:
            raise ProjectError(p, f"photo {h.tokens[0]}: {why}", rows[k + 1].line, "R")
        eo[i] = np.concatenate([x0, angles_from_matrix(rot)])


def detect(path: Path) -> bool:
    return is_patb(path)


def read(path: Path, request) -> Block:
    """The registry's entry (io/formats.py)."""
    return read_patb(path, request.encoding)
