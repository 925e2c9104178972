"""The files of an OpenSfM dataset, piece by piece: numbers and vectors of its JSON with the
line they stand on, the CRS of a gcp_list.txt, cameras, tracks.csv and
the control (ground_control_points.json, gcp_list.txt, config.yaml's GCP sigmas).  The
dataset as a Block is read by io/opensfm.py, whose text gives the conventions."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.records import decode_text, file_bytes, parse_number, split_lines, to_numbers

RECONSTRUCTIONS = ("reconstruction.json", "reconstruction_example.json")
TRACKS = ("tracks.csv", "tracks_example.csv")
GCP_JSON = "ground_control_points.json"
GCP_LIST = "gcp_list.txt"
SUPPORTED = ("perspective", "simple_radial", "radial", "brown", "fisheye", "fisheye_opencv")
UNSUPPORTED = ("fisheye62", "fisheye624", "dual", "spherical", "equirectangular")
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


def parse_crs_line(text: str) -> str:
    """The CRS of gcp_list.txt's first line: ODM's 'WGS84 UTM 32N', an EPSG code or a proj
    string (pyproj checks it later)."""
    t = text.strip()
    m = re.fullmatch(r"WGS84\s+UTM\s+(\d{1,2})\s*([NS])", t, re.IGNORECASE)
    if m and 1 <= int(m.group(1)) <= 60:
        return f"EPSG:{(32600 if m.group(2).upper() == 'N' else 32700) + int(m.group(1))}"
    return t


# ------------------------------------------------------------------ cameras
class _Camera:
    """One OpenSfM camera in baarda's terms (mm with the nominal pixel size)."""

    def __init__(self, cid: str, d, path: Path, text: str, pixel_mm: float):
        line = _line(text, "cameras", cid)
        d = _mapping(d, path, line, "cameras")
        kind = d.get("projection_type", "perspective")
        kline = _line(text, "cameras", cid, "projection_type") or line
        if kind in UNSUPPORTED:
            raise ProjectError(str(path), f"camera '{cid}': projection type {kind} is not "
                               f"supported (supported: {', '.join(SUPPORTED)})", kline,
                               "projection_type")
        if kind not in SUPPORTED:
            raise ProjectError(str(path), f"camera '{cid}': unknown projection type "
                               f"{kind!r} (supported: {', '.join(SUPPORTED)})", kline,
                               "projection_type")

        def get(key: str, default: float | None = None, positive: bool = False) -> float:
            if key not in d:
                if default is None:
                    raise ProjectError(str(path), f"camera '{cid}': no {key}", line, key)
                return default
            return _number(d[key], path, _line(text, "cameras", cid, key) or line, key,
                           positive=positive)

        self.id, self.kind = cid, kind
        self.width = get("width", positive=True)
        self.height = get("height", positive=True)
        self.size = max(self.width, self.height)
        if kind in ("perspective", "fisheye"):
            fx = fy = get("focal", positive=True)
            cx = cy = 0.0
        else:
            fx = get("focal_x", positive=True)
            fy = get("focal_y", positive=True)
            cx, cy = get("c_x", 0.0), get("c_y", 0.0)
        k1, k2 = get("k1", 0.0), get("k2", 0.0)
        k3 = k4 = p1 = p2 = 0.0
        if kind == "brown":
            k3, p1, p2 = get("k3", 0.0), get("p1", 0.0), get("p2", 0.0)
        if kind == "fisheye_opencv":
            k3, k4 = get("k3", 0.0), get("k4", 0.0)
        self.raw = {"focal_x": fx, "focal_y": fy, "c_x": cx, "c_y": cy, "k1": k1, "k2": k2,
                    "k3": k3, "k4": k4, "p1": p1, "p2": p2}
        s = self.size * pixel_mm
        self.focal_mm = fx * s
        self.pp_mm = (cx * s, -cy * s)
        self.fisheye = kind.startswith("fisheye")
        self.model = "fisheye_forward" if self.fisheye else "brown_forward"
        self.coefficients = (np.array([k1, k2, k3, k4, fy / fx - 1.0]) if self.fisheye else
                             np.array([k1, k2, k3, p2, -p1, fy / fx - 1.0]))
        self.free = {"perspective": ("c", "k1", "k2"), "simple_radial": ("c", "x0", "y0", "k1"),
                     "radial": ("c", "x0", "y0", "k1", "k2"),
                     "brown": ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "a"),
                     "fisheye": ("c", "k1", "k2"),
                     "fisheye_opencv": ("c", "x0", "y0", "k1", "k2", "k3", "k4", "a")}[kind]
        self.scale_mm = s  # mm per normalised unit

    def project(self, xc: np.ndarray) -> np.ndarray:
        """OpenSfM's projection of camera-frame points (m, 3) to normalised coordinates:
        Brown's distortion of (x/z, y/z) (OpenCV's form), then focal and principal point."""
        r = self.raw
        x, y = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
        r2 = x * x + y * y
        if self.fisheye:  # equidistant: theta = atan(r), theta_d = theta (1 + k1 theta^2 ...)
            rr = np.sqrt(r2)
            th = np.arctan(rr)
            t2 = th * th
            thd = th * (1 + t2 * (r["k1"] + t2 * (r["k2"] + t2 * (r["k3"] + t2 * r["k4"]))))
            f = np.where(rr > 0, thd / np.where(rr > 0, rr, 1.0), 1.0)
            return np.column_stack([r["focal_x"] * f * x + r["c_x"],
                                    r["focal_y"] * f * y + r["c_y"]])
        radial = 1 + r2 * (r["k1"] + r2 * (r["k2"] + r2 * r["k3"]))
        xd = x * radial + 2 * r["p1"] * x * y + r["p2"] * (r2 + 2 * x * x)
        yd = y * radial + r["p1"] * (r2 + 2 * y * y) + 2 * r["p2"] * x * y
        return np.column_stack([r["focal_x"] * xd + r["c_x"], r["focal_y"] * yd + r["c_y"]])

    def to_mm(self, xy_n: np.ndarray) -> np.ndarray:
        xy_n = np.asarray(xy_n, float).reshape(-1, 2)
        return np.column_stack([xy_n[:, 0] * self.scale_mm, -xy_n[:, 1] * self.scale_mm])

    def pixels_to_normalised(self, px: np.ndarray) -> np.ndarray:
        px = np.asarray(px, float).reshape(-1, 2)
        return np.column_stack([(px[:, 0] + 0.5 - self.width / 2) / self.size,
                                (px[:, 1] + 0.5 - self.height / 2) / self.size])


# ------------------------------------------------------------------ tracks
def read_tracks(path: Path) -> tuple[list[str], list[str], np.ndarray, np.ndarray]:
    """(image per row, track per row, xy (n, 2) normalised, line number per row)."""
    lines = split_lines(decode_text(file_bytes(path), str(path)))
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


def _gcp_list(path: Path, cameras_of_shot: dict[str, _Camera]):
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
