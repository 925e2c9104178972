"""One chunk of an Agisoft Metashape / PhotoScan document (a project's doc.xml or a cameras
XML of File > Export > Cameras) into a Block: the conventions both readers share.

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
from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.block.rotation import angles_from_matrix
from baarda.errors import ProjectError
from baarda.io.xmltree import Node

ROTATION_TOLERANCE = 1e-6  # |R R^T - I| of a rotation Metashape writes with 17 digits
DEFAULT_TIE_PX = 1.0  # Metashape's default tie point accuracy [px]
DEFAULT_PROJECTION_PX = 0.5  # Metashape's default marker projection accuracy [px]
DEFAULT_MARKER_M = 0.005  # Metashape's default marker accuracy [m]
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".tif", ".tiff", ".png", ".dng", ".raw", ".bmp")
CALIBRATION_TERMS = ("f", "fx", "fy", "cx", "cy", "b1", "b2", "skew", "k1", "k2", "k3", "k4",
                     "p1", "p2", "p3", "p4")
BROWN_FORWARD = ("k1", "k2", "k3", "p1", "p2", "a")


@dataclass
class Sensor:
    id: str
    label: str
    width: int
    height: int
    pixel_mm: float | None
    c_px: float  # f + b1 (or fx) [px]
    pp_px: tuple[float, float]  # from the image centre, y down [px]
    coef: np.ndarray  # brown_forward: k1 k2 k3 p1 p2 a
    fixed: bool
    free: tuple[str, ...]
    dropped: dict[str, float]
    calibration_class: str


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


def numbers(node: Node, where: str, n: int, what: str) -> np.ndarray:
    """The n numbers of `node`'s text; ProjectError naming the element and line."""
    try:
        v = np.array([float(t) for t in node.text.split()])
    except ValueError:
        raise ProjectError(where, f"<{what}>: {n} numbers expected", node.line, what) from None
    if len(v) != n or not np.isfinite(v).all():
        raise ProjectError(where, f"<{what}>: {n} finite numbers expected, found "
                           f"{len(v)}", node.line, what)
    return v


def attr_number(node: Node, name: str, where: str, default: float | None = None) -> float:
    s = node.attrib.get(name)
    if s is None:
        if default is None:
            raise ProjectError(where, f"<{node.tag}> has no attribute {name}", node.line, name)
        return default
    try:
        v = float(s)
    except ValueError:
        v = float("nan")
    if not np.isfinite(v):
        raise ProjectError(where, f"<{node.tag} {name}='{s}'>: a number expected", node.line,
                           name)
    return v


def check_rotation(r: np.ndarray, where: str, node: Node, what: str) -> None:
    err = float(np.abs(r @ r.T - np.eye(3)).max())
    det = float(np.linalg.det(r))
    if not (err <= ROTATION_TOLERANCE) or det <= 0:
        raise ProjectError(where, f"{what} is not a rotation (|R R^T - I| = {err:.3g}, det "
                           f"{det:.3g}; expected an orthonormal matrix with determinant +1)",
                           node.line, node.tag)


def _flag(node: Node, name: str, default: bool = True) -> bool:
    return node.attrib.get(name, "true" if default else "false").lower() in ("true", "1")


def _properties(node: Node) -> dict[str, str]:
    return {p.attrib.get("name", ""): p.attrib.get("value", "") for p in node.findall("property")}


def read_sensor(s: Node, where: str, pixel_mm: float | None) -> Sensor:
    sid = s.attrib.get("id", "")
    label = s.attrib.get("label", sid)
    cals = s.findall("calibration")
    cal = next((c for c in cals if c.attrib.get("class") == "adjusted"), None) or \
        next(iter(cals), None)
    res = s.find("resolution") or (cal.find("resolution") if cal is not None else None)
    if res is None:
        raise ProjectError(where, f"sensor {sid}: no <resolution width height>", s.line,
                           "resolution")
    w, h = attr_number(res, "width", where), attr_number(res, "height", where)
    props = _properties(s)
    pm = None
    if "pixel_width" in props and "pixel_height" in props:
        try:
            pw, ph = float(props["pixel_width"]), float(props["pixel_height"])
        except ValueError:
            pw = ph = float("nan")
        if not (pw > 0 and ph > 0):
            raise ProjectError(where, f"sensor {sid}: pixel size {props['pixel_width']} x "
                               f"{props['pixel_height']} mm: positive numbers expected",
                               s.line, "pixel_width")
        if abs(pw - ph) > 1e-9 * pw:
            raise ProjectError(where, f"sensor {sid}: non-square pixels ({pw} x {ph} mm) are "
                               "not read", s.line, "pixel_height")
        pm = pw
    fixed = props.get("fixed", "false").lower() == "true"
    if cal is None:
        if "focal_length" not in props or pm is None:
            raise ProjectError(where, f"sensor {sid}: no <calibration> and no focal_length "
                               "and pixel size to start from", s.line, "calibration")
        val = {"f": float(props["focal_length"]) / pm}
        kind = "none (the sensor's focal_length)"
    else:
        val = {}
        for c in cal.children:
            if c.tag not in CALIBRATION_TERMS or not c.text.strip():
                continue  # resolution, date, ...
            try:
                val[c.tag] = float(c.text)
            except ValueError:
                raise ProjectError(where, f"sensor {sid}: <{c.tag}> '{c.text.strip()}': a "
                                   "number expected", c.line, c.tag) from None
        kind = cal.attrib.get("class", "")
    if "f" in val:
        fx, fy = val["f"] + val.get("b1", 0.0), val["f"]
        cx, cy = val.get("cx", 0.0), val.get("cy", 0.0)
    elif "fx" in val:
        fx, fy = val["fx"], val.get("fy", val["fx"])
        cx, cy = val.get("cx", w / 2) - w / 2, val.get("cy", h / 2) - h / 2
    else:
        raise ProjectError(where, f"sensor {sid}: the calibration has no <f> (or <fx>)",
                           (cal or s).line, "f")
    if not (fx > 0 and fy > 0):
        raise ProjectError(where, f"sensor {sid}: focal length {fx:g} px: positive expected",
                           (cal or s).line, "f")
    coef = np.array([val.get("k1", 0.0), val.get("k2", 0.0), val.get("k3", 0.0),
                     val.get("p1", 0.0), -val.get("p2", 0.0), fy / fx - 1.0])
    dropped = {k: val[k] for k in ("k4", "p3", "p4", "b2", "skew") if val.get(k, 0.0) != 0}
    free: tuple[str, ...] = ()
    if not fixed and cal is not None:
        free = ("c", "x0", "y0") + tuple(k for k in ("k1", "k2", "k3", "p1", "p2") if k in val)
        if "b1" in val:
            free += ("a",)
    return Sensor(sid, label, int(w), int(h), pm, fx, (cx, cy), coef, fixed, free, dropped,
                  kind)


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


def _transform(chunk: Node, where: str) -> tuple[np.ndarray, np.ndarray, float, Node]:
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
    return rot, tr, sc, t


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
    rot, tr, sc, _ = _transform(chunk, where)
    notes: list[str] = []
    ids, labels, sensor_of, poses = [], [], [], []
    skipped = 0
    for c in _cameras(chunk):
        cid = c.attrib.get("id")
        if cid is None:
            raise ProjectError(where, "<camera> without id", c.line, "id")
        t = c.find("transform")
        if not _flag(c, "enabled") or t is None:
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
    gnss = sum(1 for r in refs if r is not None and _flag(r, "enabled", False))
    bars = chunk.find("scalebars")
    if gnss or (bars is not None and bars.children):
        notes.append("not read: " + ", ".join(
            w for w in ([f"{gnss} camera reference position(s) (GNSS)"] if gnss else [])
            + (["scale bars"] if bars is not None and bars.children else [])))
    if not ids:
        raise ProjectError(where, "no enabled and aligned camera (a <camera> with a "
                           "<transform>) in the chunk", chunk.line, "cameras")
    acc = {k: float(v) for k, v in _properties(chunk.find("settings") or Node("", {}, 0)).items()
           if k.startswith("accuracy_") and _is_float(v)}
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
            enabled = _flag(ref, "enabled")
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
                unpinned += not _flag(loc, "pinned")
                projections.append((mid, loc.attrib.get("camera_id", ""),
                                    attr_number(loc, "x", where), attr_number(loc, "y", where),
                                    loc.line))
    return Chunk(where, chunk.attrib.get("label", ""), sensors, ids, labels, sensor_of,
                 np.array(poses), mids, mlabels, np.array(mxyz).reshape(-1, 3),
                 np.array(msig).reshape(-1, 3), np.array(men, bool), projections,  # type: ignore[arg-type]
                 rot, tr, sc, _crs(chunk), acc, notes, unpinned)


def _is_float(v: str) -> bool:
    try:
        float(v)
    except ValueError:
        return False
    return True


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


def to_block(ch: Chunk, ties: TiePoints | None, *, pixel_mm: float, sigma_px: float | None,
             name: str, all_cameras: list[str] | None = None) -> Block:
    """The Block of a chunk and its tie points (module docstring).  `all_cameras`: the ids
    of every camera of the chunk (enabled or not), to tell a projection on a camera left
    out from one on a camera that does not exist."""
    where = ch.where
    notes = list(ch.notes)
    index = {c: i for i, c in enumerate(ch.camera_ids)}
    every = set(all_cameras or []) | set(ch.camera_ids)
    sensor_ids = sorted(set(ch.camera_sensor), key=list(ch.sensors).index)
    sens = [ch.sensors[s] for s in sensor_ids]
    pix = np.array([s.pixel_mm or pixel_mm for s in sens])
    if any(s.pixel_mm is None for s in sens):
        notes.append(f"Metashape: no pixel size in the sensor: nominal {pixel_mm:g} mm")
    for s in sens:
        if s.dropped:
            notes.append(f"sensor {s.label}: " + ", ".join(f"{k} = {v:g}" for k, v in
                                                           s.dropped.items())
                         + " not held (baarda's brown_forward has no K4, P3, P4 or skew): "
                         "the camera is approximated without them")
    cam_of = np.array([sensor_ids.index(s) for s in ch.camera_sensor])
    cameras = Cameras([s.label if [t.label for t in sens].count(s.label) == 1 else
                       f"{s.label}#{s.id}" for s in sens],
                      np.array([s.c_px for s in sens]) * pix,
                      np.array([[s.pp_px[0], -s.pp_px[1]] for s in sens]) * pix[:, None],
                      np.full(len(sens), "brown_forward", dtype=object),
                      np.array([s.coef for s in sens]), None,
                      tuple(s.free for s in sens), pixel_mm=pix)
    flip = np.diag([1.0, -1.0, -1.0])
    r_cam = ch.rotation @ ch.camera_pose[:, :3, :3] @ flip
    x0 = ch.translation + ch.scale * ch.camera_pose[:, :3, 3] @ ch.rotation.T
    frame = _geocentric_frame(ch)
    if frame is not None:  # the transform gives earth-centred coordinates: into the frame
        r_cam = frame.rot @ r_cam
        x0 = (x0 - frame.origin_ecef) @ frame.rot.T
    names = [Path(s).stem if Path(s).suffix.lower() in IMAGE_SUFFIXES else s
             for s in ch.camera_labels]
    if len(set(names)) < len(names):
        names = list(ch.camera_labels)
    if len(set(names)) < len(names):
        names = [f"{lab}#{cid}" for lab, cid in zip(ch.camera_labels, ch.camera_ids, strict=True)]
    photos = Photos(names, cam_of, np.full(len(names), "", dtype=object),
                    np.column_stack([x0, angles_from_matrix(r_cam)]))
    tie_px = sigma_px if sigma_px is not None else ch.accuracy.get("accuracy_tiepoints",
                                                                    DEFAULT_TIE_PX)
    mark_px = sigma_px if sigma_px is not None else ch.accuracy.get("accuracy_projections",
                                                                     DEFAULT_PROJECTION_PX)
    # marker projections
    mindex = {m: k for k, m in enumerate(ch.marker_ids)}
    rows = []
    out_of = 0
    for mid, cid, u, v, line in ch.projections:  # type: ignore[misc]
        if cid not in index:
            if cid not in every:
                raise ProjectError(where, f"marker {mid}: a projection on camera {cid}, "
                                   f"which the chunk does not have", line, "camera_id")
            out_of += 1
            continue
        rows.append((index[cid], mindex[mid], u, v))
    if out_of:
        notes.append(f"{out_of} marker projection(s) on cameras left out not used")
    if ch.unpinned:
        notes.append(f"{ch.unpinned} marker projection(s) not pinned (placed by Metashape, "
                     "not confirmed on the image): used as measured")
    mp = np.array(rows, float).reshape(-1, 4)
    seen = np.bincount(mp[:, 1].astype(int), minlength=len(ch.marker_ids))
    keep_m = seen > 0
    if (~keep_m).any():
        notes.append(f"{int((~keep_m).sum())} marker(s) without a projection left out: "
                     + ", ".join(np.array(ch.marker_labels)[~keep_m][:10]))
    m_new = np.cumsum(keep_m) - 1
    has_ref = np.isfinite(ch.marker_xyz).all(axis=1)
    role = np.where(has_ref & ch.marker_enabled, "control",
                    np.where(has_ref, "check", "tie")).astype(object)
    pt_ids = [str(s) for s in np.array(ch.marker_labels, dtype=object)[keep_m]]
    xyz = ch.marker_xyz[keep_m] if frame is None else frame.to_local(ch.marker_xyz[keep_m])
    sig = np.where((role == "control")[:, None], ch.marker_sigma, np.nan)[keep_m]
    roles = role[keep_m]
    photo = mp[:, 0].astype(np.int64)
    point = m_new[mp[:, 1].astype(np.int64)]
    uv = mp[:, 2:4]
    sigma = np.full(len(mp), mark_px)
    n_mark = len(mp)
    if ties is not None:
        if set(ties.ids) & set(pt_ids):
            raise ProjectError(ties.source, "tie point ids repeat marker labels: "
                               + ", ".join(sorted(set(ties.ids) & set(pt_ids))[:5]))
        txyz = ties.xyz if ties.in_crs else ch.translation + ch.scale * ties.xyz @ ch.rotation.T
        if frame is not None:
            txyz = (txyz - frame.origin_ecef) @ frame.rot.T
        tcam = np.array([index.get(c, -1) for c in ties.camera], np.int64)
        bad = [c for c in ties.camera if c not in every]
        if bad:
            raise ProjectError(ties.source, f"projections on camera {bad[0]}, which the chunk "
                               "does not have", None, "camera_id")
        ok = tcam >= 0
        if not ok.all():
            notes.append(f"{int((~ok).sum())} tie point projection(s) on cameras left out "
                         "not used")
        base = len(pt_ids)
        pt_ids += ties.ids
        xyz = np.vstack([xyz, txyz])
        sig = np.vstack([sig, np.full((len(ties.ids), 3), np.nan)])
        roles = np.concatenate([roles, np.full(len(ties.ids), "tie", dtype=object)])
        photo = np.concatenate([photo, tcam[ok]])
        point = np.concatenate([point, base + ties.point[ok]])
        uv = np.vstack([uv, ties.uv[ok]])
        sigma = np.concatenate([sigma, np.full(int(ok.sum()), tie_px)])
    cam = cam_of[photo]
    w = np.array([s.width for s in sens], float)[cam]
    h = np.array([s.height for s in sens], float)[cam]
    p = pix[cam]
    xy = np.column_stack([(uv[:, 0] - w / 2) * p, (h / 2 - uv[:, 1]) * p])
    image = ImagePoints(photo, point, xy, sigma * p)
    points = GroundPoints(pt_ids, xyz, sig, roles)
    n_ctrl, n_chk = int(np.sum(roles == "control")), int(np.sum(roles == "check"))
    notes.insert(0, f"Metashape chunk '{ch.label}': {len(names)} camera(s), "
                 f"{len(ch.marker_ids)} marker(s) ({n_ctrl} control, {n_chk} check), "
                 f"{n_mark} marker projection(s) at {mark_px:g} px, "
                 + (f"{len(ties.ids)} tie point(s) from {ties.source} at {tie_px:g} px"
                    if ties is not None else "no tie points")
                 + f"; chunk transform scale {ch.scale:.6g}"
                 + (f", CRS {ch.crs}" if ch.crs else ", no CRS (local or none)"))
    settings = Settings(name=name, angle_unit="deg",
                        sigma_image_um=float(tie_px * pix[0] * 1e3), crs=ch.crs,
                        datum="control" if n_ctrl else "free")
    if n_ctrl:
        settings.sigma_control_m = tuple(float(v) for v in  # type: ignore[assignment]
                                         np.median(sig[roles == "control"], axis=0))
    if frame is not None:
        notes.append(f"the chunk transform gives earth-centred coordinates ({ch.crs}): the "
                     "block is adjusted in a local east-north-up frame at the markers' mean, "
                     "results converted back to the CRS")
    return Block(settings, cameras, photos, image, points, source=where, notes=notes,
                 frame=frame)


def _geocentric_frame(ch: Chunk):
    """The LocalFrame of a chunk in a geographic or projected CRS (Metashape's transform then
    maps to earth-centred coordinates on the CRS's ellipsoid; its references are in the
    CRS), at the mean of the markers' references; None for a chunk without a CRS."""
    if ch.crs is None:
        return None
    from baarda.block.crs import LocalFrame

    ref = ch.marker_xyz[np.isfinite(ch.marker_xyz).all(axis=1)]
    if not len(ref):
        raise ProjectError(ch.where, f"the chunk is in {ch.crs} but no marker has reference "
                           "coordinates: the local frame cannot be placed", None, "markers")
    try:
        return LocalFrame(ch.crs, ref.mean(axis=0))
    except ProjectError as e:
        raise ProjectError(ch.where, f"the chunk's CRS {ch.crs}: {e.detail}", None,
                           "reference") from None
