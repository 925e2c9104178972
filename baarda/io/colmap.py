"""COLMAP sparse models: cameras, images, points3D in text (.txt) or binary (.bin) form.

`read_colmap(folder)` returns a `ColmapModel` that holds the files faithfully (ids, camera
models and parameters, poses, all 2D keypoints, tracks, colours, errors), so that
`write_colmap` writes them back unchanged (round trip).  The conversion to and from a
baarda Block (conventions below) is in colmap_block.py.

Conventions (https://colmap.github.io/format.html) and their conversion:

* pose (q, t) maps world to camera: X_cam = R(q) X + t, camera x right, y down, z forward;
  q = (qw, qx, qy, qz).  baarda: u = R_b^T (X - X0) with y up and z backward, so
  R_b = R^T diag(1, -1, -1) and X0 = -R^T t.
* pixels: origin at the upper-left corner of the image (pixel centres at +0.5), y down.
  baarda mm: x = (col - W/2) p, y = (H/2 - row) p fx/fy with a nominal pixel size p
  (`pixel_mm`, default 0.001 mm: 1 px = 1 µm, so image residuals in µm read as pixels);
  camera constant c = fx p, principal point ((cx - W/2) p, (H/2 - cy) p fx/fy).
* lens: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL (k), RADIAL (k1, k2), OPENCV (k1, k2, p1,
  p2), FULL_OPENCV with k4 = k5 = k6 = 0 (k3) -> ``brown_forward`` with (k1, k2, k3,
  p2, -p1) (COLMAP's y axis points down and its decentring terms are swapped).  Other
  models are read and written but not converted.
* observations: keypoints with a 3D point; a point measured twice in one image keeps the
  first keypoint (a note names the others).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.records import is_number, parse_number, read_lines

# model id -> (name, number of parameters)
MODELS = {0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4), 2: ("SIMPLE_RADIAL", 4),
          3: ("RADIAL", 5), 4: ("OPENCV", 8), 5: ("OPENCV_FISHEYE", 8), 6: ("FULL_OPENCV", 12),
          7: ("FOV", 5), 8: ("SIMPLE_RADIAL_FISHEYE", 4), 9: ("RADIAL_FISHEYE", 5),
          10: ("THIN_PRISM_FISHEYE", 12), 11: ("RAD_TAN_THIN_PRISM_FISHEYE", 16)}
MODEL_ID = {name: (i, n) for i, (name, n) in MODELS.items()}
FILES = ("cameras", "images", "points3D")


@dataclass
class ColmapCamera:
    model: str
    width: int
    height: int
    params: np.ndarray


@dataclass
class ColmapImage:
    qvec: np.ndarray  # (4,) qw, qx, qy, qz
    tvec: np.ndarray  # (3,)
    camera_id: int
    name: str
    xys: np.ndarray  # (k, 2) pixels
    point3D_ids: np.ndarray  # (k,) int64, -1 = none


@dataclass
class ColmapPoint:
    xyz: np.ndarray
    rgb: np.ndarray  # (3,) uint8
    error: float
    image_ids: np.ndarray  # (n,) int64
    point2D_idxs: np.ndarray  # (n,) int64


@dataclass
class ColmapModel:
    cameras: dict[int, ColmapCamera] = field(default_factory=dict)
    images: dict[int, ColmapImage] = field(default_factory=dict)
    points3D: dict[int, ColmapPoint] = field(default_factory=dict)


# ----------------------------------------------------------------- rotations
def qvec_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (qw, qx, qy, qz) (normalised first)."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def matrix_to_qvec(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (qw >= 0) of a rotation matrix (Shepperd's method)."""
    r = np.asarray(r, float)
    tr = np.trace(r)
    cand = np.array([tr, r[0, 0], r[1, 1], r[2, 2]])
    k = int(np.argmax(cand))
    if k == 0:
        s = 2 * np.sqrt(1 + tr)
        q = [s / 4, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif k == 1:
        s = 2 * np.sqrt(1 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [(r[2, 1] - r[1, 2]) / s, s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif k == 2:
        s = 2 * np.sqrt(1 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s]
    else:
        s = 2 * np.sqrt(1 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4]
    q = np.asarray(q)
    return q if q[0] >= 0 else -q


# ----------------------------------------------------------------- text files
def _data_lines(path: Path) -> list[tuple[int, str]]:
    return [(i, s) for i, s in enumerate(read_lines(path), start=1)
            if s.strip() and not s.lstrip().startswith("#")]


def _floats(values, names, path: Path, line: int) -> np.ndarray:
    """Finite numbers of the fields `names` of one line."""
    return np.array([parse_number(v, str(path), line, c)
                     for v, c in zip(values, names, strict=True)])


def _int(s: str, path: Path, line: int, what: str) -> int:
    try:
        return int(s)
    except ValueError:
        raise ProjectError(str(path), f"'{s}' is not an integer", line, what) from None


def _read_cameras_txt(path: Path) -> dict[int, ColmapCamera]:
    out = {}
    for no, s in _data_lines(path):
        p = s.split()
        if len(p) < 4:
            raise ProjectError(str(path), "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]", no)
        cid = _int(p[0], path, no, "CAMERA_ID")
        if p[1] not in MODEL_ID:
            raise ProjectError(str(path), f"unknown camera model '{p[1]}'", no, "MODEL")
        n = MODEL_ID[p[1]][1]
        if len(p) != 4 + n:
            raise ProjectError(str(path), f"{p[1]} has {n} parameters, found {len(p) - 4}", no,
                               "PARAMS")
        if cid in out:
            raise ProjectError(str(path), f"duplicate camera id {cid}", no, "CAMERA_ID")
        out[cid] = ColmapCamera(p[1], _int(p[2], path, no, "WIDTH"),
                                _int(p[3], path, no, "HEIGHT"),
                                _floats(p[4:], ["PARAMS"] * len(p[4:]), path, no))
    return out


def _read_images_txt(path: Path) -> dict[int, ColmapImage]:
    raw = read_lines(path)
    out = {}
    i = 0
    while i < len(raw):
        s = raw[i]
        if not s.strip() or s.lstrip().startswith("#"):
            i += 1
            continue
        no = i + 1
        p = s.split(maxsplit=9)
        if len(p) < 10:
            raise ProjectError(str(path), "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID "
                               "NAME", no)
        iid = _int(p[0], path, no, "IMAGE_ID")
        q = _floats(p[1:5], ("QW", "QX", "QY", "QZ"), path, no)
        t = _floats(p[5:8], ("TX", "TY", "TZ"), path, no)
        cid = _int(p[8], path, no, "CAMERA_ID")
        pts = raw[i + 1].split() if i + 1 < len(raw) else []
        if len(pts) % 3:
            raise ProjectError(str(path), "POINTS2D must be triples (X, Y, POINT3D_ID)", no + 1,
                               "POINTS2D")
        arr = np.array(pts, dtype=object).reshape(-1, 3)
        try:
            xys = arr[:, :2].astype(float)
            ids = arr[:, 2].astype(np.int64)
        except ValueError:
            bad = next(v for v in pts if not is_number(v))
            raise ProjectError(str(path), f"'{bad}' is not a number", no + 1,
                               "POINTS2D") from None
        if iid in out:
            raise ProjectError(str(path), f"duplicate image id {iid}", no, "IMAGE_ID")
        out[iid] = ColmapImage(q, t, cid, p[9].strip(), xys.reshape(-1, 2), ids)
        i += 2
    return out


def _read_points_txt(path: Path) -> dict[int, ColmapPoint]:
    out = {}
    for no, s in _data_lines(path):
        p = s.split()
        if len(p) < 8 or (len(p) - 8) % 2:
            raise ProjectError(str(path), "expected POINT3D_ID X Y Z R G B ERROR and (IMAGE_ID, "
                               "POINT2D_IDX) pairs", no)
        pid = _int(p[0], path, no, "POINT3D_ID")
        xyz = _floats(p[1:4], "XYZ", path, no)
        rgb = np.array([_int(v, path, no, c) for v, c in zip(p[4:7], "RGB", strict=True)])
        if np.any((rgb < 0) | (rgb > 255)):
            raise ProjectError(str(path), "colour outside 0..255", no, "RGB")
        err = parse_number(p[7], str(path), no, "ERROR")
        track = np.array([_int(v, path, no, "TRACK") for v in p[8:]], dtype=np.int64)
        if pid in out:
            raise ProjectError(str(path), f"duplicate point id {pid}", no, "POINT3D_ID")
        out[pid] = ColmapPoint(xyz, rgb.astype(np.uint8), err, track[0::2], track[1::2])
    return out


# --------------------------------------------------------------- binary files
class _Reader:
    def __init__(self, path: Path):
        if not path.is_file():
            raise ProjectError(str(path), "file not found")
        self.path, self.data, self.pos = path, path.read_bytes(), 0

    def take(self, fmt: str, what: str):
        size = struct.calcsize(fmt)
        if self.pos + size > len(self.data):
            raise ProjectError(str(self.path), f"file ends inside {what} (byte {self.pos})")
        out = struct.unpack_from(fmt, self.data, self.pos)
        self.pos += size
        return out

    def array(self, dtype: str, count: int, what: str) -> np.ndarray:
        dt = np.dtype(dtype)
        size = dt.itemsize * count
        if count < 0 or self.pos + size > len(self.data):
            raise ProjectError(str(self.path), f"file ends inside {what} (byte {self.pos})")
        out = np.frombuffer(self.data, dt, count, self.pos).copy()
        self.pos += size
        return out

    def string(self, what: str) -> str:
        end = self.data.find(b"\0", self.pos)
        if end < 0:
            raise ProjectError(str(self.path), f"unterminated {what} (byte {self.pos})")
        s = self.data[self.pos:end].decode("utf-8", "replace")
        self.pos = end + 1
        return s

    def done(self) -> None:
        if self.pos != len(self.data):
            raise ProjectError(str(self.path), f"{len(self.data) - self.pos} bytes after the "
                               "last record")


def _read_cameras_bin(path: Path) -> dict[int, ColmapCamera]:
    r = _Reader(path)
    (n,) = r.take("<Q", "the camera count")
    out = {}
    for k in range(n):
        cid, mid, w, h = r.take("<iiQQ", f"camera {k}")
        if mid not in MODELS:
            raise ProjectError(str(path), f"camera {cid}: unknown model id {mid}")
        name, npar = MODELS[mid]
        out[cid] = ColmapCamera(name, int(w), int(h), r.array("<f8", npar, f"camera {cid}"))
    r.done()
    return out


def _read_images_bin(path: Path) -> dict[int, ColmapImage]:
    r = _Reader(path)
    (n,) = r.take("<Q", "the image count")
    out = {}
    for k in range(n):
        vals = r.take("<I7dI", f"image {k}")
        iid = vals[0]
        name = r.string(f"name of image {iid}")
        (npts,) = r.take("<Q", f"keypoint count of image {iid}")
        rec = r.array([("x", "<f8"), ("y", "<f8"), ("id", "<i8")], npts,
                      f"keypoints of image {iid}")
        out[iid] = ColmapImage(np.array(vals[1:5]), np.array(vals[5:8]), vals[8], name,
                               np.column_stack([rec["x"], rec["y"]]), rec["id"].astype(np.int64))
    r.done()
    return out


def _read_points_bin(path: Path) -> dict[int, ColmapPoint]:
    r = _Reader(path)
    (n,) = r.take("<Q", "the point count")
    out = {}
    for k in range(n):
        vals = r.take("<Q3d3BdQ", f"point {k}")
        pid = vals[0]
        rec = r.array([("im", "<u4"), ("idx", "<u4")], vals[8], f"track of point {pid}")
        out[pid] = ColmapPoint(np.array(vals[1:4]), np.array(vals[4:7], np.uint8), vals[7],
                               rec["im"].astype(np.int64), rec["idx"].astype(np.int64))
    r.done()
    return out


# ------------------------------------------------------------------ public API
def is_colmap_model(path: str | Path) -> bool:
    p = Path(path)
    return p.is_dir() and (all((p / f"{f}.txt").is_file() for f in FILES) or
                           all((p / f"{f}.bin").is_file() for f in FILES))


def read_colmap(folder: str | Path) -> ColmapModel:
    """Read a COLMAP sparse model folder (binary files preferred when both exist)."""
    folder = Path(folder)
    if all((folder / f"{f}.bin").is_file() for f in FILES):
        model = ColmapModel(_read_cameras_bin(folder / "cameras.bin"),
                            _read_images_bin(folder / "images.bin"),
                            _read_points_bin(folder / "points3D.bin"))
        src = folder / "images.bin"
    elif all((folder / f"{f}.txt").is_file() for f in FILES):
        model = ColmapModel(_read_cameras_txt(folder / "cameras.txt"),
                            _read_images_txt(folder / "images.txt"),
                            _read_points_txt(folder / "points3D.txt"))
        src = folder / "images.txt"
    else:
        raise ProjectError(str(folder), "not a COLMAP model folder (cameras, images, points3D "
                           ".txt or .bin)")
    _check(model, src, folder)
    return model


def _check(model: ColmapModel, src: Path, folder: Path) -> None:
    for iid, im in model.images.items():
        if im.camera_id not in model.cameras:
            raise ProjectError(str(src), f"image {iid} uses unknown camera {im.camera_id}")
        bad = im.point3D_ids[(im.point3D_ids != -1) &
                             ~np.isin(im.point3D_ids, list(model.points3D))]
        if len(bad):
            raise ProjectError(str(src), f"image {iid} refers to unknown 3D point {bad[0]}")
    pfile = folder / ("points3D.bin" if src.suffix == ".bin" else "points3D.txt")
    for pid, p in model.points3D.items():
        for iid, idx in zip(p.image_ids, p.point2D_idxs, strict=True):
            im = model.images.get(int(iid))
            if im is None or idx >= len(im.xys) or im.point3D_ids[idx] != pid:
                raise ProjectError(str(pfile), f"point {pid}: track element ({iid}, {idx}) "
                                   "does not point back to this point")
