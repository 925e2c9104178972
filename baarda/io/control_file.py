"""Control point files (`--control FILE`, `baarda.read(control=FILE)`), in two formats:

* DBAT's text format (as DBAT's loadcpt reads it): comma separated lines
  ``id[, name], X, Y, Z[, sigmas]`` [m], '#' comments.  The name column is there when the
  header comment names it (``# Id, name, X, ...``) or most lines' second field is not a
  number (one line whose X is not a number is an error naming its line and column, not a
  shift of every line's columns); after X, Y, Z come no sigma (fixed control, as DBAT holds
  it), one (sigma of X, Y and Z), two (sigma XY, sigma Z) or three (sigma X, Y, Z).  A sigma
  of 0 is fixed.
* a native ``ground_points.csv`` (a header line with ``point``, ``X``, ``Y``, ``Z``;
  docs/format.md): roles control, fixed and check, sigmas from its columns or
  `sigma_control_m`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.records import parse_number
from baarda.io.text_files import ENCODING, decode_text, file_bytes, is_number, split_lines


@dataclass(frozen=True)
class ControlFile:
    """The points of a control file: ids, xyz (k, 3) [m], sigma (k, 3) [m; 0 fixed; NaN
    for check points and unobserved coordinates], role ('control' or 'check')."""
    path: str
    ids: list[str]
    xyz: np.ndarray
    sigma: np.ndarray
    role: np.ndarray


def _is_native(lines: list[str]) -> bool:
    for line in lines:
        s = line.strip()
        if s and not s.startswith("#"):
            names = [c.strip() for c in s.split(",")]
            return "point" in names and all(c in names for c in "XYZ")
    return False


def read_control_file(path: str | Path, encoding: str = ENCODING,
                      sigma_control_m=(0.05, 0.05, 0.05)) -> ControlFile:
    """A control file in DBAT's text format or a native ground_points.csv (module
    docstring); ProjectError naming the file, line and field of the first problem."""
    spath = str(path)
    lines = split_lines(decode_text(file_bytes(path, "control file not found"), spath,
                                    encoding))
    if _is_native(lines):
        from baarda.io.project import read_ground_points

        g_ids, g_xyz, g_sig, role, _ = read_ground_points(Path(path), sigma_control_m, encoding)
        return ControlFile(spath, list(g_ids), g_xyz, g_sig, np.asarray(role, dtype=object))
    rows = []
    header = None
    for no, line in enumerate(lines, start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            header = s.lstrip("#").strip()
            continue
        rows.append((no, [f.strip() for f in s.split(",")]))
    if not rows:
        raise ProjectError(spath, "no control points (expected lines 'id, name, X, Y, Z"
                           "[, sigmas]' or a ground_points.csv with a header line)")
    # a name column when most lines' second field is not a number (one mistyped number does
    # not shift every line's columns: it is an error of its own line)
    named = 2 * sum(len(f) > 1 and not is_number(f[1]) for _, f in rows) > len(rows)
    if header and not named and rows:
        fields = [h.strip().lower() for h in header.split(",")]
        named = len(fields) > 1 and fields[1] in ("name", "label")
    ids, xyz, sig = [], [], []
    for no, f in rows:
        values = f[2:] if named else f[1:]
        if not 3 <= len(values) <= 6:
            what = "id, name, X, Y, Z" if named else "id, X, Y, Z"
            raise ProjectError(spath, f"expected {what} and 0 to 3 standard deviations "
                               f"(comma separated), found {len(f)} fields", no)
        if not f[0]:
            raise ProjectError(spath, "empty point id", no, "id")
        names = ["X", "Y", "Z", *{1: ["sigma"], 2: ["sigma_XY", "sigma_Z"],
                                  3: ["sigma_X", "sigma_Y", "sigma_Z"]}.get(len(values) - 3,
                                                                             [])]
        v = [parse_number(x, spath, no, n) for x, n in zip(values, names, strict=True)]
        s = (v[3:6] if len(v) == 6 else [v[3], v[3], v[4]] if len(v) == 5 else
             [v[3]] * 3 if len(v) == 4 else [0.0] * 3)
        for k, value in enumerate(v[3:]):
            if value < 0:
                raise ProjectError(spath, "standard deviation must not be negative (0: "
                                   "fixed)", no, names[3 + k])
        ids.append(f[0])
        xyz.append(v[:3])
        sig.append(s)
    seen: dict[str, int] = {}
    for (no, _), pid in zip(rows, ids, strict=True):
        if pid in seen:
            raise ProjectError(spath, f"duplicate point id '{pid}' (first on line "
                               f"{seen[pid]})", no, "id")
        seen[pid] = no
    return ControlFile(spath, ids, np.array(xyz, float), np.array(sig, float),
                       np.full(len(ids), "control", dtype=object))
