"""MicMac / IGN aerial blocks: a folder of tie points, control, GNSS/IMU orientations and an
IGN camera description (docs/formats.md, the IGN UltraCam block of ../shared/data).

* `*liaisons*.mes`: tie points, `point image x y` (pixels, origin upper left, y down);
* `*.APP`: control, `point n X Y Z` (the CRS of the orientations; n is ignored);
* `*.MES`: image measurements of the control, as the tie points;
* `*.opk` / `*.OPK`: orientations, `image X Y Z omega phi kappa camera` (m, degrees) after a
  header of 1 to 5 lines; `trajectograhie.opk` preferred;
* the IGN camera `.xml` (`<sensor>`): frame w x h px, principal point and focal length
  (`<focal><pt3d>`) in pixels, pixel size in m;
* `ImAerien.xml` (optional): the images of the block (else every image of the tie points
  with an orientation).

Conventions (checked by reprojection, tests/io/test_micmac.py): R = R_x(omega) R_y(phi)
R_z(kappa) from camera to object, angles in degrees, the collinearity of docs/format.md;
image x = (x_px - ppx) p, y = (ppy - y_px) p in mm with p the pixel size; c = focal_px p.
The orientations are GNSS/IMU results: they are the photos' approximations and their GNSS
positions and IMU attitudes as observations (default sigmas GNSS_SIGMA_M, IMU_SIGMA_DEG;
the lever arm and boresight are already applied in such files).  The CRS is Lambert-93
(EPSG:2154) with ellipsoidal heights, so the block is adjusted in a local east-north-up
frame.  Strips are the `x00015` part of the IGN image names.  Points measured on one image
are left out and counted.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from baarda.block.photo_block import (
    Block,
    Cameras,
    GnssObservations,
    GroundPoints,
    ImagePoints,
    ImuObservations,
    Photos,
    Settings,
)
from baarda.errors import ProjectError
from baarda.io.records import parse_number
from baarda.io.text_files import whole_lines
from baarda.io.xmltree import Node, parse_xml

CRS = "EPSG:2154"  # Lambert-93, the IGN's and MicMac's SysCo of this data
GNSS_SIGMA_M = (0.10, 0.10, 0.15)
IMU_SIGMA_DEG = 0.005
IMAGE_SIGMA_PX = 0.5
CONTROL_SIGMA_M = (0.05, 0.05, 0.05)
PREFERRED_ORIENTATIONS = "trajectograhie.opk"


def _tie_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.glob("*.mes") if "liaison" in p.name.lower())


def _sensor(folder: Path) -> Path | None:
    """The first IGN camera description of the folder (a .xml whose root is <sensor>)."""
    found = _sensors(_parsed(folder))
    return found[0][0] if found else None


def _parsed(folder: Path) -> list[tuple[Path, Node | ProjectError | None]]:
    """Each .xml of the folder (_camera_files) parsed once: its root, the ProjectError
    parsing it raised, or None for one that is not a regular file (a FIFO would block the
    reader)."""
    out: list[tuple[Path, Node | ProjectError | None]] = []
    for p in _camera_files(folder):
        if not p.is_file():
            out.append((p, None))
            continue
        try:
            out.append((p, parse_xml(p)))
        except ProjectError as e:
            out.append((p, e))
    return out


Parsed = list[tuple[Path, "Node | ProjectError | None"]]


def _sensors(parsed: Parsed) -> list[tuple[Path, Node | None]]:
    """The IGN camera descriptions among the parsed files: those whose root element is
    <sensor> (a comment or declaration of any length may come before it), with their root;
    a file that does not parse counts (root None) when it names <sensor>, so that reading
    it names its error."""
    out: list[tuple[Path, Node | None]] = []
    for p, root in parsed:
        if isinstance(root, Node):
            if root.tag == "sensor":
                out.append((p, root))
        elif isinstance(root, ProjectError):
            try:
                if b"<sensor>" in p.read_bytes().lower():
                    out.append((p, None))
            except OSError:
                continue
    return out


def _camera_files(folder: Path) -> list[Path]:
    """Every .xml of the folder other than ImAerien.xml: each must parse (a camera
    description cut short is no longer recognisable by its head, and would silently hand
    the block to its sister camera)."""
    return [p for p in sorted(folder.glob("*.xml")) if p.name != "ImAerien.xml"]


def is_micmac(path: str | Path) -> bool:
    """A folder with MicMac tie points, orientations (.opk) and an IGN camera description."""
    p = Path(path)
    return (p.is_dir() and bool(_tie_files(p)) and _sensor(p) is not None
            and any(q.suffix.lower() == ".opk" for q in p.iterdir()))


def _lines(path: Path):
    """(line number, fields) of the non-empty lines of a text file written whole (empty, or
    a last line without its line end: refused as cut short)."""
    for n, line in enumerate(whole_lines(path), start=1):
        fields = line.split()
        if fields:
            yield n, fields


def read_sensor(path: Path, root: Node | None = None) -> dict:
    """The IGN camera description: width, height (px), ppx, ppy, focal (px), pixel (mm);
    root: the file's root element when already parsed."""
    if root is None:
        root = parse_xml(path)
    if root.tag != "sensor":
        raise ProjectError(str(path), "not an IGN camera description (<sensor>)", root.line)

    def value(*tags: str) -> float:
        node = root
        for t in tags:
            nxt = node.find(t)
            if nxt is None:
                raise ProjectError(str(path), f"no <{'/'.join(tags)}>", node.line, tags[-1])
            node = nxt
        return parse_number((node.text or "").strip(), str(path), node.line, tags[-1])

    name = root.find("name")
    out: dict[str, Any] = {"name": (name.text or "").strip() if name is not None
                           else path.stem,
           "width": value("usefull-frame", "rect", "w"),
           "height": value("usefull-frame", "rect", "h"),
           "ppx": value("focal", "pt3d", "x"), "ppy": value("focal", "pt3d", "y"),
           "focal": value("focal", "pt3d", "z"),
           "pixel_mm": value("pixel_size") * 1e3}
    if out["focal"] <= 0 or out["pixel_mm"] <= 0:
        raise ProjectError(str(path), "focal length and pixel size must be positive")
    return out


def read_orientations(path: Path, lines: list[tuple[int, list[str]]] | None = None
                      ) -> dict[str, tuple[np.ndarray, int]]:
    """Image name -> ((X, Y, Z, omega, phi, kappa) in m and degrees, line) of an .opk file;
    header lines (text in the coordinate fields) are skipped.  lines: the file's (_lines)
    when already read."""
    out: dict[str, tuple[np.ndarray, int]] = {}
    for n, f in (_lines(path) if lines is None else lines):
        try:
            values = np.array([float(v) for v in f[1:7]]) if len(f) >= 7 else None
        except ValueError:
            values = None
        if values is None:
            if not out and n <= 5:
                continue  # a header line before the first orientation
            raise ProjectError(str(path), "expected 'image X Y Z omega phi kappa [camera]' "
                               "with numbers", n)
        if not np.isfinite(values).all():
            raise ProjectError(str(path), "a coordinate or angle is not finite", n)
        out[f[0]] = (values, n)
    return out


def _measurements(path: Path, images: dict[str, int]) -> list[tuple[str, int, float, float]]:
    """(point, image index, x_px, y_px) of the measurements on the block's images."""
    out = []
    for n, f in _lines(path):
        if len(f) != 4:
            raise ProjectError(str(path), "expected 'point image x y'", n)
        name = Path(f[1]).stem
        if name not in images:
            continue
        out.append((f[0], images[name], parse_number(f[2], str(path), n, "x"),
                    parse_number(f[3], str(path), n, "y")))
    return out


def _image_list(folder: Path) -> list[str] | None:
    """The images of ImAerien.xml (MMVII's SetOfName: <el>"name.tif"</el> under
    <SetOfName>), read with the XML parser: a file cut short is refused, naming its line."""
    p = folder / "ImAerien.xml"
    if not p.is_file():
        return None
    root = parse_xml(p)
    sets = [n for n in _walk(root) if n.tag == "SetOfName"]
    if len(sets) != 1:
        raise ProjectError(str(p), f"expected one <SetOfName> list of images, found "
                           f"{len(sets)}", root.line)
    names = []
    for el in sets[0].children:
        if el.tag != "el":
            raise ProjectError(str(p), f"<{el.tag}> in <SetOfName>: expected <el>", el.line)
        name = el.text.strip().strip('"').strip()
        if not name:
            raise ProjectError(str(p), "an empty image name", el.line, "el")
        names.append(Path(name).stem)
    if not names:
        raise ProjectError(str(p), "<SetOfName> lists no image", sets[0].line)
    return names


def _walk(node):
    yield node
    for c in node.children:
        yield from _walk(c)


def _camera(folder: Path, parsed: Parsed,
            lines: list[tuple[int, list[str]]], names: list[str]) -> tuple[Path, dict]:
    """The IGN camera description of the block's images: the one whose <name> the
    orientations' CAMERA column (`lines`: the .opk's) names, else the only (or first) one
    of the folder (`parsed`: its .xml files, _parsed)."""
    sensors = {}
    for p, root in parsed:
        if isinstance(root, ProjectError):
            raise root
        if root is None:
            root = parse_xml(p)
        if root.tag == "sensor":
            sensors[p] = read_sensor(p, root)
    if not sensors:
        raise ProjectError(str(folder), "no IGN camera description (.xml with <sensor>)")
    column = {f[0]: f[7] for _, f in lines if len(f) >= 8}
    wanted = {column[n] for n in names if n in column}
    if len(wanted) == 1:
        name = wanted.pop()
        for p, cam in sensors.items():
            if cam["name"] == name:
                return p, cam
    p = next(iter(sensors))
    return p, sensors[p]


def _strip(name: str) -> str:
    m = re.search(r"x(\d+)_\d+$", name)
    return m.group(1) if m else ""


def read_micmac(folder: str | Path, *, orientations: str | Path | None = None,
                gnss_sigma_m: tuple[float, float, float] = GNSS_SIGMA_M,
                imu_sigma_deg: float = IMU_SIGMA_DEG,
                image_sigma_px: float = IMAGE_SIGMA_PX) -> Block:
    """A MicMac/IGN aerial block (module docstring).  orientations: the .opk file (default
    trajectograhie.opk, else the only .opk of the folder)."""
    folder = Path(folder)
    parsed = _parsed(folder)
    if not _sensors(parsed):
        raise ProjectError(str(folder), "no IGN camera description (.xml with <sensor>)")
    opks = sorted(q for q in folder.iterdir() if q.suffix.lower() == ".opk")
    if orientations is not None:
        opk = Path(orientations)
    elif (folder / PREFERRED_ORIENTATIONS).is_file():
        opk = folder / PREFERRED_ORIENTATIONS
    elif len(opks) == 1:
        opk = opks[0]
    else:
        raise ProjectError(str(folder), "several orientation files: choose one ("
                           + ", ".join(q.name for q in opks) + ")")
    opk_lines = list(_lines(opk))
    eo_by_name = read_orientations(opk, opk_lines)
    ties = _tie_files(folder)
    names = _image_list(folder)
    if names is None:
        seen: set[str] = set()
        for t in ties:
            seen |= {Path(f[1]).stem for _, f in _lines(t) if len(f) == 4}
        names = sorted(seen & set(eo_by_name))
    missing = [n for n in names if n not in eo_by_name]
    if missing:
        raise ProjectError(str(opk), f"no orientation of image {missing[0]}")
    if not names:
        raise ProjectError(str(folder), "no image with both measurements and an orientation")
    _, cam = _camera(folder, parsed, opk_lines, names)
    index = {n: i for i, n in enumerate(names)}
    p = cam["pixel_mm"]
    # measurements: tie points, then control
    meas = [m for t in ties for m in _measurements(t, index)]
    app = sorted(folder.glob("*.APP"))
    ctrl_xyz: dict[str, np.ndarray] = {}
    for a in app:
        for n, f in _lines(a):
            if len(f) != 5:
                raise ProjectError(str(a), "expected 'point n X Y Z'", n)
            ctrl_xyz[f[0]] = np.array([parse_number(f[k], str(a), n, c)
                                       for k, c in ((2, "X"), (3, "Y"), (4, "Z"))])
    for m in sorted(folder.glob("*.MES")):
        if m.suffix == ".MES":
            meas += _measurements(m, index)
    pids = list(dict.fromkeys(pt for pt, _, _, _ in meas))
    pidx = {q: j for j, q in enumerate(pids)}
    point = np.array([pidx[pt] for pt, _, _, _ in meas], dtype=np.int64)
    photo = np.array([i for _, i, _, _ in meas], dtype=np.int64)
    xy_px = np.array([[x, y] for _, _, x, y in meas]).reshape(-1, 2)
    # one measurement of a point on an image; points on one image left out
    key = photo * len(pids) + point
    _, first = np.unique(key, return_index=True)
    keep = np.zeros(len(key), bool)
    keep[first] = True
    twice = int(len(key) - keep.sum())
    rays = np.bincount(point[keep], minlength=len(pids))
    single = (rays < 2) & np.array([q not in ctrl_xyz for q in pids])
    keep &= ~single[point]
    used = np.zeros(len(pids), bool)
    used[point[keep]] = True
    new = np.cumsum(used) - 1
    ids = [q for q, u in zip(pids, used, strict=True) if u]
    point, photo, xy_px = new[point[keep]], photo[keep], xy_px[keep]
    xy = np.column_stack([(xy_px[:, 0] - cam["ppx"]) * p, (cam["ppy"] - xy_px[:, 1]) * p])
    xyz = np.full((len(ids), 3), np.nan)
    sigma = np.full((len(ids), 3), np.nan)
    role = np.full(len(ids), "tie", dtype=object)
    for j, q in enumerate(ids):
        if q in ctrl_xyz:
            xyz[j], sigma[j], role[j] = ctrl_xyz[q], CONTROL_SIGMA_M, "control"
    eo = np.array([eo_by_name[n][0] for n in names])
    eo[:, 3:] = np.radians(eo[:, 3:])
    n_ph = len(names)
    sig_img = image_sigma_px * p
    settings = Settings(name=folder.name, angle_unit="deg", sigma_image_um=sig_img * 1e3,
                        sigma_control_m=CONTROL_SIGMA_M, crs=CRS)
    notes = [f"MicMac/IGN block: camera {cam['name']} (c {cam['focal'] * p:.3f} mm, pixel "
             f"{p * 1e3:g} µm), orientations {opk.name} as approximations and as GNSS "
             f"positions (sigma {', '.join(f'{s:g}' for s in gnss_sigma_m)} m) and IMU "
             f"attitudes (sigma {imu_sigma_deg:g} deg), image sigma {image_sigma_px:g} px",
             f"{int(single.sum())} point(s) measured on one image left out"
             + (f"; {twice} repeated measurement(s) of a point on an image ignored"
                if twice else "")]
    return Block(
        settings, Cameras([cam["name"]], np.array([cam["focal"] * p]), np.zeros((1, 2)),
                          pixel_mm=np.array([p]),
                          pixel_frame=np.array([[cam["ppx"], cam["ppy"], p, p]])),
        Photos(list(names), np.zeros(n_ph, np.int64),
               np.array([_strip(n) for n in names], dtype=object), eo),
        ImagePoints(photo, point, xy, np.full(len(photo), sig_img)),
        GroundPoints(ids, xyz, sigma, role), source=str(folder), notes=notes,
        gnss=GnssObservations(np.arange(n_ph), eo[:, :3].copy(),
                              np.tile(np.asarray(gnss_sigma_m, float), (n_ph, 1))),
        imu=ImuObservations(np.arange(n_ph), eo[:, 3:].copy(),
                            np.full((n_ph, 3), np.radians(imu_sigma_deg))))
