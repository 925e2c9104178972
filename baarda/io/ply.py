"""The vertex table of a PLY file (ascii, binary_little_endian or binary_big_endian), as
Metashape stores its tie points: tracks (colours), points (x y z id) and projections per
camera (x y size id).  Only the first element is read (Metashape's files have one,
``vertex``); lists are refused.  Errors name the file (a member of a zip: "zip!member") and
what was expected.
"""

from __future__ import annotations

import numpy as np

from baarda.errors import ProjectError

TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
         "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
         "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
         "float64": "f8"}
MAX_HEADER = 64 * 1024


def read_ply(data: bytes, where: str) -> dict[str, np.ndarray]:
    """The columns (property name -> array) of the first element of the PLY file `data`;
    ProjectError naming `where` for a file that is not PLY, a type or format it does not
    know, or fewer rows than its header announces (a truncated file)."""
    end = data.find(b"end_header", 0, MAX_HEADER)
    if not data.startswith(b"ply") or end < 0:
        raise ProjectError(where, "not a PLY file (it must start with 'ply' and have an "
                           "'end_header' line)")
    nl = data.find(b"\n", end)
    body = data[nl + 1:] if nl >= 0 else b""
    header = data[:end].decode("ascii", "replace").splitlines()
    fmt, count, props = None, None, []
    for k, line in enumerate(header, 1):
        w = line.split()
        if not w or w[0] in ("ply", "comment", "obj_info"):
            continue
        if w[0] == "format" and len(w) >= 2:
            fmt = w[1]
        elif w[0] == "element" and len(w) == 3:
            if count is not None:
                break  # only the first element
            if not w[2].isdigit():
                raise ProjectError(where, f"element count '{w[2]}' is not a count", k)
            count = int(w[2])
        elif w[0] == "property" and count is not None:
            if len(w) != 3 or w[1] not in TYPES:
                raise ProjectError(where, f"property '{line.strip()}': a scalar property of "
                                   f"a known type expected ({', '.join(sorted(TYPES))})", k)
            props.append((w[2], TYPES[w[1]]))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ProjectError(where, f"PLY format '{fmt}': ascii, binary_little_endian or "
                           "binary_big_endian expected")
    if count is None or not props:
        raise ProjectError(where, "no element with properties in the PLY header")
    if fmt == "ascii":
        rows = body.decode("ascii", "replace").split("\n")
        rows = [r for r in rows if r.strip()]
        if len(rows) < count:
            raise ProjectError(where, f"the file ends early: {count} rows announced, "
                               f"{len(rows)} found (a truncated file)")
        try:
            table = np.array([r.split()[:len(props)] for r in rows[:count]], dtype=float)
        except ValueError:
            raise ProjectError(where, f"rows of {len(props)} numbers expected") from None
        if table.shape != (count, len(props)):
            raise ProjectError(where, f"rows of {len(props)} numbers expected")
        return {name: table[:, i].astype(t) for i, (name, t) in enumerate(props)}
    order = "<" if fmt == "binary_little_endian" else ">"
    dtype = np.dtype([(name, order + t) for name, t in props])
    if len(body) < count * dtype.itemsize:
        raise ProjectError(where, f"the file ends early: {count} rows of {dtype.itemsize} "
                           f"bytes announced, {len(body)} bytes found (a truncated file)")
    table = np.frombuffer(body, dtype, count)
    return {name: table[name].astype(t) for name, t in props}
