"""COLMAP text files (cameras.txt, images.txt, points3D.txt) read into arrays.

images.txt and points3D.txt are read in one pass by the numba tokeniser (colmap_kernels)
and converted as whole arrays; a file that it does not take as it is (a malformed line, a
number it does not convert exactly as Python does, anything but ASCII in the numbers) is
read again line by line by the reference readers below, which give the same arrays or the
error naming file, line and field.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.colmap_model import (
    MODEL_ID,
    ColmapCamera,
    ColmapImages,
    ColmapPoints,
    first_repeated,
)
from baarda.io.records import parse_number
from baarda.io.text_files import (
    decode_text,
    file_bytes,
    require_file,
    split_lines,
    whole_bytes,
    whole_lines,
)

INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1
BOM = b"\xef\xbb\xbf"


def _data_lines(path: Path) -> list[tuple[int, str]]:
    return [(i, s) for i, s in enumerate(whole_lines(path), start=1)
            if s.strip() and not s.lstrip().startswith("#")]


def _floats(values, names, path: Path, line: int) -> np.ndarray:
    """Finite numbers of the fields `names` of one line."""
    return np.array([parse_number(v, str(path), line, c)
                     for v, c in zip(values, names, strict=True)])


def _int(s: str, path: Path, line: int, what: str) -> int:
    try:
        v = int(s)
    except ValueError:
        raise ProjectError(str(path), f"'{s}' is not an integer", line, what) from None
    if not INT64_MIN <= v <= INT64_MAX:
        raise ProjectError(str(path), f"'{s}' is out of range", line, what)
    return v


# ----------------------------------------------------------------- cameras.txt
def read_cameras_txt(path: Path) -> dict[int, ColmapCamera]:
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


# ------------------------------------------------------------ the fast path
def _tokens(data: bytes, head: tuple[int, ...], tail: tuple[int, ...], skip_blank: bool,
            lines: int | None = None):
    """(tokens per kept line, integers, floats) of `data`, or None where the tokeniser
    does not take it (or, given `lines`, the number of lines differs)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    from baarda.io import colmap_kernels as ck

    buf = np.frombuffer(data, np.uint8)
    h = np.array(head, np.int8)
    t = np.array(tail, np.int8)
    counts = np.empty(np.count_nonzero(buf == ck.LF) + 1, np.int64)
    none64, none8 = np.empty(0, np.int64), np.empty(0, np.uint8)
    kept, nint, nflt, fbytes, bad = ck.tokens(buf, skip_blank, h, t, False, counts, none64,
                                              none8, none64)
    if bad or (lines is not None and kept != lines):
        return None
    ints = np.empty(nint, np.int64)
    fbuf = np.empty(fbytes, np.uint8)
    foff = np.zeros(nflt + 1, np.int64)
    *_, bad = ck.tokens(buf, skip_blank, h, t, True, counts, ints, fbuf, foff)
    if bad:
        return None
    strings = pa.LargeStringArray.from_buffers(nflt, pa.py_buffer(foff), pa.py_buffer(fbuf))
    try:
        floats = np.array(pc.cast(strings, pa.float64()).to_numpy(zero_copy_only=False))
    except pa.ArrowInvalid:
        return None
    return counts[:kept], ints, floats


def _file_bytes(path: Path) -> bytes:
    data = file_bytes(path)
    return data[len(BOM):] if data.startswith(BOM) else data


I, F = 0, 1
IMAGE_HEAD = (I, F, F, F, F, F, F, F, I)  # IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID
POINT_HEAD = (I, F, F, F, I, I, I, F)  # POINT3D_ID X Y Z R G B ERROR


def _images_fast(raw: list[str]) -> ColmapImages | None:
    heads, names, points = [], [], []
    i = 0
    while i < len(raw):
        s = raw[i]
        if not s.strip() or s.lstrip().startswith("#"):
            i += 1
            continue
        p = s.split(maxsplit=9)
        if len(p) < 10:
            return None
        heads.append(" ".join(p[:9]))
        names.append(p[9].strip())
        points.append(raw[i + 1] if i + 1 < len(raw) else "")
        i += 2
    n = len(heads)
    if not n:
        return ColmapImages.from_lists([], [], [], [], [], [], [])
    head = _tokens("\n".join(heads).encode(), IMAGE_HEAD, (I,), False, n)
    kp = _tokens("\n".join(points).encode(), (), (F, F, I), False, n)
    if head is None or kp is None:
        return None
    counts, ints, floats = head
    if np.any(counts != 9):
        return None
    ints, floats = ints.reshape(n, 2), floats.reshape(n, 7)
    if not np.isfinite(floats).all() or first_repeated(ints[:, 0]) >= 0:
        return None
    counts, ids, xys = kp
    if np.any(counts % 3) or not np.isfinite(xys).all():
        return None
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(counts // 3, out=offsets[1:])
    return ColmapImages(ints[:, 0].copy(), floats[:, :4].copy(), floats[:, 4:].copy(),
                        ints[:, 1].copy(), names, offsets, xys.reshape(-1, 2), ids)


def _points_fast(data: bytes) -> ColmapPoints | None:
    res = _tokens(data, POINT_HEAD, (I,), True)
    if res is None:
        return None
    counts, ints, floats = res
    m = len(counts)
    if np.any(counts < 8) or np.any(counts % 2):
        return None
    nint = counts - 4  # POINT3D_ID R G B and the track
    start = np.zeros(m + 1, np.int64)
    np.cumsum(nint, out=start[1:])
    head = start[:-1, None] + np.arange(4)
    ids, rgb = ints[head[:, 0]], ints[head[:, 1:]]
    floats = floats.reshape(m, 4)
    if (not np.isfinite(floats).all() or np.any((rgb < 0) | (rgb > 255))
            or first_repeated(ids) >= 0):
        return None
    is_track = np.ones(len(ints), bool)
    is_track[head.ravel()] = False
    track = ints[is_track]
    offsets = np.zeros(m + 1, np.int64)
    np.cumsum((counts - 8) // 2, out=offsets[1:])
    return ColmapPoints(ids, floats[:, :3].copy(), rgb.astype(np.uint8), floats[:, 3].copy(),
                        offsets, track[0::2].copy(), track[1::2].copy())


# ----------------------------------------------------------------- images.txt
def read_images_txt(path: Path) -> ColmapImages:
    raw = whole_lines(path)
    _check_last_image(raw, path)
    fast = _images_fast(raw)
    return fast if fast is not None else _images_lines(raw, path)


def _check_last_image(raw: list[str], path: Path) -> None:
    """ProjectError when the last image has no POINTS2D line (COLMAP writes one, empty for
    an image without keypoints): images.txt cut at the line end before it."""
    i = 0
    while i < len(raw):
        if not raw[i].strip() or raw[i].lstrip().startswith("#"):
            i += 1
            continue
        if i + 1 >= len(raw):
            raise ProjectError(str(path), "the last image has no POINTS2D line: the file is "
                               "cut short (COLMAP writes two lines per image)", i + 1)
        i += 2


def _images_lines(raw: list[str], path: Path) -> ColmapImages:
    """The reference: line by line, with the exact error."""
    ids, qs, ts, cams, names, xys, pids = [], [], [], [], [], [], []
    seen: set[int] = set()
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
            xy = arr[:, :2].astype(float)
            ids3 = np.array([int(v) for v in arr[:, 2]], np.int64)
            if not np.isfinite(xy).all():
                raise ValueError
        except (ValueError, OverflowError):
            for k, v in enumerate(pts):
                if k % 3 == 2:
                    _int(v, path, no + 1, "POINTS2D")
                else:
                    parse_number(v, str(path), no + 1, "POINTS2D")
            raise
        if iid in seen:
            raise ProjectError(str(path), f"duplicate image id {iid}", no, "IMAGE_ID")
        seen.add(iid)
        ids.append(iid)
        qs.append(q)
        ts.append(t)
        cams.append(cid)
        names.append(p[9].strip())
        xys.append(xy.reshape(-1, 2))
        pids.append(ids3)
        i += 2
    return ColmapImages.from_lists(ids, qs, ts, cams, names, xys, pids)


# ---------------------------------------------------------------- points3D.txt
def read_points_txt(path: Path) -> ColmapPoints:
    data = whole_bytes(path)  # empty, or a last line without its line end: cut short
    # the fast path takes printable ASCII only: text that would not decode goes to
    # _points_lines, which refuses it naming its line
    fast = _points_fast(data[len(BOM):] if data.startswith(BOM) else data)
    return fast if fast is not None else _points_lines(path)


def _points_lines(path: Path) -> ColmapPoints:
    """The reference: line by line, with the exact error."""
    ids, xyzs, rgbs, errs, ims, idxs = [], [], [], [], [], []
    seen: set[int] = set()
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
        if pid in seen:
            raise ProjectError(str(path), f"duplicate point id {pid}", no, "POINT3D_ID")
        seen.add(pid)
        ids.append(pid)
        xyzs.append(xyz)
        rgbs.append(rgb)
        errs.append(err)
        ims.append(track[0::2])
        idxs.append(track[1::2])
    return ColmapPoints.from_lists(ids, xyzs, rgbs, errs, ims, idxs)


# ---------------------------------------------------------------- truncated files
def _head_lines(path: Path, count: int, block: int = 1 << 16) -> list[str]:
    """read_lines(path)[:count], reading only as far as those lines go (the header of a
    file the reader has already taken whole)."""
    require_file(path)
    data = b""
    try:
        with open(path, "rb") as f:
            while True:
                more = f.read(block)
                data += more
                end = len(data) if not more else data.rfind(b"\n") + 1
                lines = split_lines(decode_text(data[:end], str(path)))
                if not more or len(lines) >= count:
                    return lines[:count]
    except OSError as e:
        raise ProjectError(str(path), f"cannot be read ({e.strerror or e})") from None


HEADER_COUNT = re.compile(r"#\s*Number of (cameras|images|points)\s*:\s*(\d+)")


def check_header_count(path: Path, found: int) -> None:
    """ProjectError when the count COLMAP wrote into the header of cameras.txt, images.txt
    or points3D.txt ('# Number of images: N') differs from the records read: the file was
    cut short (or edited), which would otherwise surface in the other file."""
    for no, s in enumerate(_head_lines(path, 20), start=1):
        m = HEADER_COUNT.match(s.strip())
        if m:
            said = int(m.group(2))
            if said != found:
                data = _data_lines(path)
                last = data[-1][0] if data else no
                raise ProjectError(str(path), f"holds {found} of the {said} {m.group(1)} "
                                   f"that its header names (line {no}): the file is cut short "
                                   "or was edited", last)
            return


def data_line(path: Path, k: int) -> int | None:
    """The line of the k-th record (0-based) of points3D.txt (one data line each)."""
    data = _data_lines(path)
    return data[k][0] if 0 <= k < len(data) else None
