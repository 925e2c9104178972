"""One chunk of an Agisoft Metashape / PhotoScan document (a project's doc.xml or a cameras
XML of File > Export > Cameras), read as it is (`read_chunk`), and the conventions both
readers share (io/metashape_sensor.py: the camera; io/metashape_block.py: the Block).

* sensors: ``<resolution width height>``, the pixel size (properties ``pixel_width``,
  ``pixel_height`` [mm]; without them the nominal ``--pixel-mm``), ``fixed``; the
  ``<calibration>`` of class ``adjusted`` where there is one, else ``initial``: ``f`` with
  ``cx``, ``cy`` as offsets from the image centre [px] (Metashape 1.4 on), or ``fx``, ``fy``
  with an absolute ``cx``, ``cy`` (PhotoScan up to 1.3, as DBAT reads them); ``b1``, ``b2``,
  ``k1``..``k4``, ``p1``..``p4``.  Metashape's model (its manual, appendix "Camera models"):
  x = X/Z, y = Y/Z (camera looks down +z, y down), x' = x (1 + K1 r^2 + K2 r^4 + K3 r^6 +
  K4 r^8) + P1 (r^2 + 2x^2) + 2 P2 x y, y' likewise with P2 (r^2 + 2y^2) + 2 P1 x y; u = w/2 +
  cx + x' (f + b1) + y' b2, v = h/2 + cy + y' f.  In baarda (y up, origin at the image
  centre, mm): ``brown_forward`` with c = (f + b1) p, principal point (cx p, -cy p), k1..k3,
  p1 = P1, p2 = -P2 (OpenCV's (p1, p2) are Metashape's (P2, P1)) and the aspect a = f / (f +
  b1) - 1; K4, P3, P4 and b2 have no place in it (a note names their values when not 0).
  A sensor that is ``fixed`` is held; otherwise the parameters its calibration has are the
  ones Metashape estimates (Cameras.free).
* cameras (also inside ``<group>``): enabled cameras with a ``<transform>`` (4 x 4, row
  major, camera -> chunk frame, camera frame x right, y down, z forward); others are left
  out with a note.  The chunk ``<transform>`` (rotation R, translation t, scale s; or the
  camera's component's) maps the chunk frame to the CRS: X = t + s R x.  So R_baarda = R
  R_cam diag(1, -1, -1), X0 = t + s R c_cam.  Without a chunk transform the chunk frame is
  arbitrary: an error (a block cannot have control in it), as DBAT warns.
* markers: ``<reference x y z sxy|sx sy, sz enabled>``; enabled: control, disabled: check
  point, no reference: tie point; accuracies default to the chunk's ``accuracy_markers``.
  Their projections (``<location camera_id x y>`` in the frame's ``<markers>``, pixels,
  origin at the image's upper-left corner, y down) have the sigma ``accuracy_projections``
  [px], tie points ``accuracy_tiepoints`` [px] (``--sigma-px`` replaces both).
* the CRS: the chunk's ``<reference>`` WKT: its last ``AUTHORITY["EPSG", n]`` is
  Settings.crs ("EPSG:n"); a ``LOCAL_CS`` or none: no CRS, and the transform maps to the
  references' coordinates.  With a CRS the transform maps to earth-centred coordinates on
  the CRS's ellipsoid (Metashape's `chunk.crs.project(chunk.transform.matrix.mulp(x))`):
  the block is in the east-north-up LocalFrame (block/crs.py) at the markers' mean, the
  markers' references converted into it.

Image coordinates x = (u - w/2) p, y = (h/2 - v) p [mm].  Camera reference positions (GNSS)
and scale bars are not read (noted).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from baarda.block.rotation import not_a_rotation
from baarda.errors import ProjectError
from baarda.io.metashape_sensor import Sensor, attr_number, flag, numbers, properties, read_sensor
from baarda.io.text_files import is_number
from baarda.io.xmltree import Node

ROTATION_TOLERANCE = 1e-6  # |R R^T - I| of a rotation Metashape writes with 17 digits
DEFAULT_TIE_PX = 1.0  # Metashape's default tie point accuracy [px]
DEFAULT_PROJECTION_PX = 0.5  # Metashape's default marker projection accuracy [px]
DEFAULT_MARKER_M = 0.005  # Metashape's default marker accuracy [m]
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".tif", ".tiff", ".png", ".dng", ".raw", ".bmp")


@dataclass
class Chunk:
    """What a chunk says, in Metashape's terms (pixels, chunk frame); `where`: the file."""
    where: str
    label: str
    sensors: dict[str, Sensor]
    camera_ids: list[str]
    camera_labels: list[str]
    camera_sensor: list[str]
    camera_pose: np.ndarray  # (n, 4, 4) camera -> chunk frame
    marker_ids: list[str]
    marker_labels: list[str]
    marker_xyz: np.ndarray  # (k, 3), NaN: no reference
    marker_sigma: np.ndarray  # (k, 3)
    marker_enabled: np.ndarray  # (k,) bool
    projections: list[tuple[str, str, float, float]]  # (marker id, camera id, u, v)
    rotation: np.ndarray
    translation: np.ndarray
    scale: float
    crs: str | None
    accuracy: dict[str, float]
    notes: list[str] = field(default_factory=list)
    unpinned: int = 0  # marker projections with pinned="false"

    def to_crs(self, x: np.ndarray) -> np.ndarray:
        """Chunk-frame points x (..., 3) in the chunk's reference system: t + s R x."""
        return self.translation + self.scale * x @ self.rotation.T


def check_rotation(r: np.ndarray, where: str, node: Node, what: str) -> None:
    why = not_a_rotation(r, ROTATION_TOLERANCE)
    if why is not None:
        raise ProjectError(where, f"{what} is {why}", node.line, node.tag)


def _members(chunk: Node, holder: str, tag: str) -> list[Node]:
    """The `tag` elements of the chunk's `holder`, also those inside its <group>s."""
    h = chunk.find(holder)
    out: list[Node] = []
    for c in (h.children if h is not None else []):
        if c.tag == tag:
            out.append(c)
        elif c.tag == "group":
            out.extend(c.findall(tag))
    return out


def _cameras(chunk: Node) -> list[Node]:
    return _members(chunk, "cameras", "camera")


def _markers(chunk: Node) -> list[Node]:
    return _members(chunk, "markers", "marker")


def _transform(chunk: Node, where: str) -> tuple[np.ndarray, np.ndarray, float]:
    """The chunk's transform (or its first component's); ProjectError when there is none."""
    t = chunk.find("transform")
    if t is None:
        comps = chunk.find("components")
        found = [c for c in (comps.findall("component") if comps is not None else [])
                 if c.find("transform") is not None]
        if len(found) > 1:
            raise ProjectError(where, f"{len(found)} components with their own <transform>: "
                               "only a chunk of one component is read (merge them, or "
                               "export each)", found[1].line, "component")
        t = found[0].find("transform") if found else None
    if t is None or t.find("rotation") is None:
        raise ProjectError(where, f"chunk '{chunk.attrib.get('label', '')}' has no "
                           "<transform> (rotation, translation, scale): its coordinates are "
                           "in Metashape's arbitrary internal frame, not a reference system; "
                           "reference the chunk (markers or camera positions) and optimise "
                           "before exporting", chunk.line, "transform")
    rn, tn, sn = t.find("rotation"), t.find("translation"), t.find("scale")
    assert rn is not None
    rot = numbers(rn, where, 9, "rotation").reshape(3, 3)
    check_rotation(rot, where, rn, "the chunk's <rotation>")
    tr = numbers(tn, where, 3, "translation") if tn is not None else np.zeros(3)
    sc = float(numbers(sn, where, 1, "scale")[0]) if sn is not None else 1.0
    if not sc > 0:
        raise ProjectError(where, f"<scale> {sc:g}: positive expected", t.line, "scale")
    return rot, tr, sc


def _crs(chunk: Node) -> str | None:
    ref = chunk.find("reference")
    text = ref.text if ref is not None else ""
    if not text.strip() or text.strip().upper().startswith("LOCAL_CS"):
        return None
    codes = re.findall(r'AUTHORITY\["EPSG",\s*"?(\d+)"?\]', text)
    return f"EPSG:{codes[-1]}" if codes else None


def read_chunk(chunk: Node, frame: Node | None, where: str,
               pixel_mm: float | None = None) -> Chunk:
    """The chunk `chunk` with its marker projections from `frame` (a psz frame, or the
    chunk itself when its projections are in it: a cameras XML)."""
    sens = chunk.find("sensors")
    sensors = {}
    for s in (sens.findall("sensor") if sens is not None else []):
        sensors[s.attrib.get("id", "")] = read_sensor(s, where, pixel_mm)
    rot, tr, sc = _transform(chunk, where)
    notes: list[str] = []
    ids, labels, sensor_of, poses = [], [], [], []
    skipped = 0
    for c in _cameras(chunk):
        cid = c.attrib.get("id")
        if cid is None:
            raise ProjectError(where, "<camera> without id", c.line, "id")
        t = c.find("transform")
        if not flag(c, "enabled") or t is None:
            skipped += 1
            continue
        m = numbers(t, where, 16, "transform").reshape(4, 4)
        check_rotation(m[:3, :3], where, t, f"camera {cid} ({c.attrib.get('label', '')}): "
                       "the rotation of its <transform>")
        if np.abs(m[3] - [0, 0, 0, 1]).max() > 1e-9:
            raise ProjectError(where, f"camera {cid}: the last row of <transform> must be "
                               "0 0 0 1", t.line, "transform")
        s = c.attrib.get("sensor_id", "")
        if s not in sensors:
            raise ProjectError(where, f"camera {cid}: sensor_id '{s}' is not a sensor of the "
                               f"chunk ({', '.join(sensors) or 'none'})", c.line, "sensor_id")
        ids.append(cid)
        labels.append(c.attrib.get("label", cid))
        sensor_of.append(s)
        poses.append(m)
    if skipped:
        notes.append(f"{skipped} camera(s) disabled or not aligned (no <transform>) left out")
    refs = [c.find("reference") for c in _cameras(chunk)]
    gnss = sum(1 for r in refs if r is not None and flag(r, "enabled", False))
    bars = chunk.find("scalebars")
    if gnss or (bars is not None and bars.children):
        notes.append("not read: " + ", ".join(
            w for w in ([f"{gnss} camera reference position(s) (GNSS)"] if gnss else [])
            + (["scale bars"] if bars is not None and bars.children else [])))
    if not ids:
        raise ProjectError(where, "no enabled and aligned camera (a <camera> with a "
                           "<transform>) in the chunk", chunk.line, "cameras")
    acc = {k: float(v) for k, v in properties(chunk.find("settings") or Node("", {}, 0)).items()
           if k.startswith("accuracy_") and is_number(v)}
    default_sigma = acc.get("accuracy_markers", DEFAULT_MARKER_M)
    mids, mlabels, mxyz, msig, men = [], [], [], [], []
    for m in _markers(chunk):
        mid = m.attrib.get("id")
        if mid is None:
            raise ProjectError(where, "<marker> without id", m.line, "id")
        ref = m.find("reference")
        xyz = np.full(3, np.nan)
        sig = np.full(3, np.nan)
        enabled = False
        if ref is not None and all(k in ref.attrib for k in "xyz"):
            xyz = np.array([attr_number(ref, k, where) for k in "xyz"])
            sxyz = attr_number(ref, "sxyz", where, default_sigma)
            sxy = attr_number(ref, "sxy", where, sxyz)
            sig = np.array([attr_number(ref, "sx", where, sxy), attr_number(ref, "sy", where,
                                                                            sxy),
                            attr_number(ref, "sz", where, sxyz)])
            enabled = flag(ref, "enabled")
        mids.append(mid)
        mlabels.append(m.attrib.get("label", mid))
        mxyz.append(xyz)
        msig.append(sig)
        men.append(enabled)
    known = set(mids)
    projections = []
    unpinned = 0
    for holder in (frame, chunk) if frame is not chunk else (chunk,):
        ms = holder.find("markers") if holder is not None else None
        for m in (ms.findall("marker") if ms is not None else []):
            mid = m.attrib.get("marker_id")
            if mid is None:
                continue  # a marker definition of the chunk, not a projection
            if mid not in known:
                raise ProjectError(where, f"projections of marker {mid}, which the chunk's "
                                   "<markers> do not define", m.line, "marker_id")
            for loc in m.findall("location"):
                unpinned += not flag(loc, "pinned")
                projections.append((mid, loc.attrib.get("camera_id", ""),
                                    attr_number(loc, "x", where), attr_number(loc, "y", where),
                                    loc.line))
    return Chunk(where, chunk.attrib.get("label", ""), sensors, ids, labels, sensor_of,
                 np.array(poses), mids, mlabels, np.array(mxyz).reshape(-1, 3),
                 np.array(msig).reshape(-1, 3), np.array(men, bool), projections,  # type: ignore[arg-type]
                 rot, tr, sc, _crs(chunk), acc, notes, unpinned)


@dataclass
class TiePoints:
    """Tie points in the chunk frame: ids (k,), xyz (k, 3), and their projections: camera
    ids (m,), point index (m,), u, v (m, 2) [px]; `source` names their files."""
    ids: list[str]
    xyz: np.ndarray
    camera: list[str]
    point: np.ndarray
    uv: np.ndarray
    source: str
    in_crs: bool = False  # xyz already in the CRS (a Bundler file of the chunk)
