"""The files of an OpenSfM dataset, piece by piece: numbers and vectors of its JSON with the
line they stand on, the CRS of a gcp_list.txt, tracks.csv and the control
(ground_control_points.json, gcp_list.txt, config.yaml's GCP sigmas).  The cameras are
io/opensfm_camera.py's; the dataset as a Block is read by io/opensfm.py, whose text gives
the conventions."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from baarda.errors import ProjectError
from baarda.io.gcp_list import parse_crs_line
from baarda.io.records import parse_number, to_numbers
from baarda.io.text_files import decode_text, file_bytes, split_lines, whole_lines

if TYPE_CHECKING:
    from baarda.io.opensfm_camera import OpenSfmCamera

RECONSTRUCTIONS = ("reconstruction.json", "reconstruction_example.json")
TRACKS = ("tracks.csv", "tracks_example.csv")
GCP_JSON = "ground_control_points.json"
GCP_LIST = "gcp_list.txt"
CONTROL_SIGMA_M = (0.05, 0.05, 0.05)  # without gcp_horizontal_sd / gcp_vertical_sd


# ------------------------------------------------------------------ small helpers
def _load_json(path: Path):
    text = decode_text(file_bytes(path), str(path))
    try:
        return json.loads(text), text
    except json.JSONDecodeError as e:
        raise ProjectError(str(path), f"not valid JSON: {e.msg}", e.lineno,
                           f"character {e.colno}") from None
    except (ValueError, RecursionError) as e:  # e.g. an integer of thousands of digits
        raise ProjectError(str(path), f"not valid JSON: {e}") from None


def _line(text: str, *keys: str) -> int | None:
    """The line of the last of `keys` found one after the other as JSON keys ("key"), or
    of the last one found (error messages only)."""
    pos, found = 0, None
    for k in keys:
        i = text.find(json.dumps(str(k)), pos)
        if i < 0:
            break
        pos, found = i + 1, i
    return None if found is None else text.count("\n", 0, found) + 1


def _at(line) -> int | None:
    """A line number, or a function that finds it (called only for an error message: the
    search runs through the JSON text)."""
    return line() if callable(line) else line


def _number(value, path: Path, line, field: str, *, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ProjectError(str(path), f"{value!r} is not a number", _at(line), field)
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise ProjectError(str(path), f"{value!r} is not a finite number", _at(line), field)
    if positive and v <= 0:
        raise ProjectError(str(path), f"{value!r} must be positive", _at(line), field)
    return v


def _vector(value, n: int, path: Path, line, field: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != n:
        raise ProjectError(str(path), f"expected a list of {n} numbers, found "
                           f"{str(value)[:60]}", _at(line), field)
    return np.array([_number(v, path, line, field) for v in value])


def _mapping(value, path: Path, line, field: str) -> dict:
    if not isinstance(value, dict):
        raise ProjectError(str(path), f"expected an object, found {type(value).__name__}",
                           _at(line), field)
    return value


def utm_crs(lon: float, lat: float) -> str:
    """The WGS84 UTM zone of a place, as 'EPSG:326zz' / 'EPSG:327zz'."""
    zone = min(60, max(1, int((lon + 180) // 6) + 1))
    return f"EPSG:{(32600 if lat >= 0 else 32700) + zone}"


# ------------------------------------------------------------------ tracks
def read_tracks(path: Path) -> tuple[list[str], list[str], np.ndarray, np.ndarray]:
    """(image per row, track per row, xy (n, 2) normalised, line number per row); a file
    that is empty or whose last line has no line end is refused as cut short."""
    lines = whole_lines(path)
    start = 1 if lines and lines[0].startswith("OPENSFM_TRACKS_VERSION") else 0
    images, tracks, xs, ys, nos = [], [], [], [], []
    for n, line in enumerate(lines[start:], start=start + 1):
        if not line.strip():
            continue
        f = line.split("\t") if "\t" in line else line.split()
        if len(f) < 5:
            raise ProjectError(str(path), f"expected 'image track feature x y ...' (tab "
                               f"separated), found {len(f)} field(s)", n)
        images.append(f[0])
        tracks.append(f[1].strip())
        xs.append(f[3])
        ys.append(f[4])
        nos.append(n)
    lines_no = np.asarray(nos, dtype=np.int64)
    xy = np.column_stack([_column(xs, path, lines_no, "x"), _column(ys, path, lines_no, "y")])
    return images, tracks, xy.reshape(-1, 2), lines_no


def _column(values: list[str], path: Path, lines: np.ndarray, name: str) -> np.ndarray:
    """A column of finite numbers (io/records.to_numbers: the first bad value named)."""
    return to_numbers(np.asarray(values, dtype=str), str(path), lines, name)


# ------------------------------------------------------------------ control
def _gcp_json(path: Path, shots: dict[str, int]):
    """[(id, lla or None, [(shot, (x, y) normalised, line)], line)] of ground_control_points."""
    doc, text = _load_json(path)
    doc = _mapping(doc, path, 1, "points")
    pts = doc.get("points", [])
    if not isinstance(pts, list):
        raise ProjectError(str(path), "'points' must be a list", _line(text, "points"),
                           "points")
    out = []
    pos = 0
    for k, p in enumerate(pts):
        pid = str(p.get("id", "")) if isinstance(p, dict) else ""
        i = text.find('"id"', pos)
        line = text.count("\n", 0, i) + 1 if i >= 0 else None
        pos = i + 1 if i >= 0 else pos
        p = _mapping(p, path, line, f"points[{k}]")
        if not pid:
            raise ProjectError(str(path), f"control point {k + 1} has no id", line, "id")
        lla = None
        if p.get("position") is not None:
            q = _mapping(p["position"], path, line, "position")
            for key in ("latitude", "longitude"):
                if key not in q:
                    raise ProjectError(str(path), f"control point {pid}: no {key}", line, key)
            lat = _number(q["latitude"], path, line, "latitude")
            lon = _number(q["longitude"], path, line, "longitude")
            alt = _number(q["altitude"], path, line, "altitude") if "altitude" in q \
                else math.nan
            if abs(lat) > 90 or abs(lon) > 360:
                raise ProjectError(str(path), f"control point {pid}: latitude/longitude out "
                                   "of range", line, "position")
            lla = (lon, lat, alt)
        obs = []
        for o in p.get("observations", []) or []:
            o = _mapping(o, path, line, "observations")
            shot = str(o.get("shot_id", ""))
            xy = _vector(o.get("projection"), 2, path, line, "projection")
            if shot in shots:
                obs.append((shot, xy, line))
        out.append((pid, lla, obs, line))
    return out


def _gcp_list(path: Path, cameras_of_shot: dict[str, OpenSfmCamera]):
    """(crs, [(id, xyz in the CRS, [(shot, xy normalised, line)], line)]) of ODM's
    gcp_list.txt; points without a name are told apart by their coordinates."""
    lines = split_lines(decode_text(file_bytes(path), str(path)))
    head = [(n, s) for n, s in enumerate(lines, start=1) if s.strip()
            and not s.lstrip().startswith("#")]
    if not head:
        raise ProjectError(str(path), "empty: the first line names the CRS")
    crs = parse_crs_line(head[0][1])
    points: dict[str, list] = {}
    for n, s in head[1:]:
        f = s.split()
        if len(f) < 6:
            raise ProjectError(str(path), "expected 'X Y Z px py image [name]'", n)
        vals = []
        for v, name in zip(f[:5], ("X", "Y", "Z", "px", "py"), strict=True):
            vals.append(parse_number(v, str(path), n, name))
        image = f[5]
        pid = f[6] if len(f) > 6 else f"{f[0]}_{f[1]}_{f[2]}"
        xyz = np.array(vals[:3])
        entry = points.setdefault(pid, [pid, xyz, [], n])
        if not np.allclose(entry[1], xyz, rtol=0, atol=1e-6):
            raise ProjectError(str(path), f"control point {pid} has other coordinates on "
                               f"line {entry[3]}", n, "X")
        if image in cameras_of_shot:
            xy = cameras_of_shot[image].pixels_to_normalised(np.array(vals[3:5]))[0]
            entry[2].append((image, xy, n))
    return crs, list(points.values())


def _config_sigmas(folder: Path) -> tuple[float, float, float] | None:
    p = folder / "config.yaml"
    if not p.is_file():
        return None
    h = v = None
    for n, line in enumerate(split_lines(decode_text(file_bytes(p), str(p))), start=1):
        m = re.match(r"\s*(gcp_horizontal_sd|gcp_vertical_sd)\s*:\s*([^#]+)", line)
        if m:
            val = _number(_float_or_text(m.group(2).strip()), p, n, m.group(1),
                          positive=True)
            if m.group(1) == "gcp_horizontal_sd":
                h = val
            else:
                v = val
    if h is None and v is None:
        return None
    h = h if h is not None else CONTROL_SIGMA_M[0]
    v = v if v is not None else CONTROL_SIGMA_M[2]
    return (h, h, v)


def _float_or_text(s: str):
    try:
        return float(s)
    except ValueError:
        return s
