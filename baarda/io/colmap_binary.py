"""COLMAP binary files (cameras.bin, images.bin, points3D.bin) read into arrays.

A record of images.bin or points3D.bin is a fixed header followed by a variable-length
array, so the records are first walked (colmap_kernels: positions and counts only, each
count checked against the bytes left) and then gathered into flat arrays.  No count is
trusted before the file is known to hold its data: a count that claims more is an error,
never an allocation of that size.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.colmap_model import MODELS, ColmapCamera, ColmapImages, ColmapPoints
from baarda.io.text_files import file_bytes

IMAGE_HEADER = np.dtype([("id", "<u4"), ("qvec", "<f8", 4), ("tvec", "<f8", 3),
                         ("camera_id", "<u4")])  # 64 bytes, then the name
KEYPOINT = np.dtype([("x", "<f8"), ("y", "<f8"), ("id", "<i8")])  # 24 bytes
POINT_HEADER = np.dtype([("id", "<u8"), ("xyz", "<f8", 3), ("rgb", "u1", 3),
                         ("error", "<f8"), ("track_length", "<u8")])  # 51 bytes
TRACK_ELEMENT = np.dtype([("image_id", "<u4"), ("point2D_idx", "<u4")])  # 8 bytes
NAME_AND_COUNT = 1 + 8  # the shortest name (its NUL) and the keypoint count


class _Reader:
    def __init__(self, path: Path):
        self.path, self.data, self.pos = path, file_bytes(path), 0

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

    def fail(self, message: str):
        raise ProjectError(str(self.path), message)

    def done(self, pos: int) -> None:
        if pos != len(self.data):
            self.fail(f"{len(self.data) - pos} bytes after the last record")


def read_cameras_bin(path: Path) -> dict[int, ColmapCamera]:
    r = _Reader(path)
    (n,) = r.take("<Q", "the camera count")
    out = {}
    for k in range(n):
        cid, mid, w, h = r.take("<iiQQ", f"camera {k}")
        if mid not in MODELS:
            r.fail(f"camera {cid}: unknown model id {mid}")
        name, npar = MODELS[mid]
        at = r.pos
        params = r.array("<f8", npar, f"camera {cid}")
        if not np.isfinite(params).all():
            r.fail(f"camera {cid}: a parameter is not a finite number (byte "
                   f"{at + 8 * int(np.argmin(np.isfinite(params)))})")
        out[cid] = ColmapCamera(name, int(w), int(h), params)
    r.done(r.pos)
    return out


def _finite(r: _Reader, values: np.ndarray, starts: np.ndarray, ids: np.ndarray,
            what: str, fields: str) -> None:
    """ProjectError naming the record (its id and byte) of the first non-finite value of
    `values` (one row per record, starting at byte `starts` + the field's offset)."""
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        r.fail(f"{what} {ids[k]}: {fields} not a finite number (record at byte "
               f"{int(starts[k])})")


def _records(buf: np.ndarray, starts: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """The fixed-size records of `dtype` at byte positions `starts`."""
    from baarda.io import colmap_kernels as ck

    n = len(starts)
    size = np.full(n, dtype.itemsize, np.int64)
    return ck.gather(buf, starts, size, n * dtype.itemsize).view(dtype)


def read_images_bin(path: Path) -> ColmapImages:
    from baarda.io import colmap_kernels as ck

    r = _Reader(path)
    (n,) = r.take("<Q", "the image count")
    buf = np.frombuffer(r.data, np.uint8)
    # n records take at least n * 73 bytes: a larger count fails within this many
    walk = min(n, (len(buf) - 8) // (IMAGE_HEADER.itemsize + NAME_AND_COUNT) + 1)
    rec, name_end, count, end, fail, k, at = ck.walk_images(buf, walk)
    if fail:
        if fail == 1:
            r.fail(f"file ends inside image {k} (byte {at})")
        (iid,) = struct.unpack_from("<I", r.data, rec[k])
        what = {2: "unterminated name", 3: "file ends inside keypoint count",
                4: "file ends inside keypoints"}[fail]
        r.fail(f"{what} of image {iid} (byte {at})")
    r.done(end)
    head = _records(buf, rec, IMAGE_HEADER)
    names = [r.data[a + IMAGE_HEADER.itemsize:b].decode("utf-8", "replace")
             for a, b in zip(rec.tolist(), name_end.tolist(), strict=True)]
    kp_bytes = count * KEYPOINT.itemsize
    kp = ck.gather(buf, name_end + NAME_AND_COUNT, kp_bytes, int(kp_bytes.sum())).view(KEYPOINT)
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(count, out=offsets[1:])
    _finite(r, np.column_stack([head["qvec"], head["tvec"]]), rec, head["id"], "image",
            "QW QX QY QZ TX TY TZ:")
    kx = np.column_stack([kp["x"], kp["y"]])
    bad = ~np.isfinite(kx).all(axis=1)
    if bad.any():
        j = int(np.argmax(bad))
        k = int(np.searchsorted(offsets, j, side="right")) - 1
        r.fail(f"image {head['id'][k]}: keypoint {j - offsets[k]} is not a finite number "
               f"(byte {int(name_end[k]) + NAME_AND_COUNT + KEYPOINT.itemsize * (j - offsets[k])})")
    return ColmapImages(head["id"].astype(np.int64), head["qvec"].copy(), head["tvec"].copy(),
                        head["camera_id"].astype(np.int64), names, offsets,
                        np.column_stack([kp["x"], kp["y"]]), kp["id"].astype(np.int64))


def read_points_bin(path: Path) -> ColmapPoints:
    from baarda.io import colmap_kernels as ck

    r = _Reader(path)
    (n,) = r.take("<Q", "the point count")
    buf = np.frombuffer(r.data, np.uint8)
    walk = min(n, (len(buf) - 8) // POINT_HEADER.itemsize + 1)
    rec, count, end, fail, k, at = ck.walk_points(buf, walk)
    if fail == 1:
        r.fail(f"file ends inside point {k} (byte {at})")
    if fail == 2:
        (pid,) = struct.unpack_from("<Q", r.data, rec[k])
        r.fail(f"file ends inside track of point {pid} (byte {at})")
    r.done(end)
    head = _records(buf, rec, POINT_HEADER)
    tr_bytes = count * TRACK_ELEMENT.itemsize
    track = ck.gather(buf, rec + POINT_HEADER.itemsize, tr_bytes,
                      int(tr_bytes.sum())).view(TRACK_ELEMENT)
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(count, out=offsets[1:])
    _finite(r, np.column_stack([head["xyz"], head["error"]]), rec, head["id"], "point",
            "X Y Z ERROR:")
    return ColmapPoints(head["id"].astype(np.int64), head["xyz"].copy(), head["rgb"].copy(),
                        head["error"].copy(), offsets, track["image_id"].astype(np.int64),
                        track["point2D_idx"].astype(np.int64))
