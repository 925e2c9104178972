"""DBAT script projects (Damped Bundle Adjustment Toolbox, Boerlin & Grussenmeyer).

A DBAT script is an XML file (``<document dbat_script_version="1.0">``) naming comma
separated files of control/check points, images and image measurements, and the camera.
What is read, and how it is converted:

* image measurements ``x, y`` in pixels, origin at the upper-left image corner, y down
  (DBAT: mm = pixel * pixel size, then y flipped, no half-pixel shift).  baarda's image
  frame: origin at the image centre, y up:  x_mm = (x_px - w/2) p_x,
  y_mm = (h/2 - y_px) p_y, with p = sensor size / image size in pixels.
* principal point ``pp`` in mm from the upper-left sensor corner, y down -> (pp_x - W/2,
  H/2 - pp_y) mm; camera constant ``cc`` (default: ``focal``).
* lens distortion ``K`` (K1..K3), ``P`` (P1, P2) of DBAT's backward model 3 ->
  ``brown_backward`` with the same coefficients (ideal = u + delta(u)); other DBAT models
  are rejected.  The aspect enters through the pixel sizes: DBAT scales pixels by the pixel
  height and multiplies x by px/py after subtracting pp, so the x of pp is in units of the
  pixel height and becomes pp_x px/py.  Skew must be 0.
* the camera: a ``<camera>`` element or a DBAT camera file (``<cameras><file>``), with the
  script's ``set_initial_values`` applied (io/dbat_operations.py).
* self-calibration: the parameters that the script's ``set_bundle_estimate_params``
  estimates, flag by flag as DBAT applies them (``all``, ``cc``, ``pp``, ``px``, ``py``,
  ``aspect``, ``skew``, ``K``, ``P``, ``K1``..``K3``, ``P1``, ``P2``; io/dbat_operations.py);
  the camera becomes baarda's ``dbat3`` model (DBAT's model 3 exactly: the affine
  [1 + b1, b2; 0, 1] after pp, then Brown) in DBAT's own frame: pixels scaled by the pixel
  height in x and y, b1 = 1 - aspect (DBAT's 'as').
* image sigma ``sxy`` (pixels; the ``sxy`` attribute of the file element overrides the
  column) -> mm with the pixel height (DBAT's pixel size).
* control points with sigmas -> control; without sigma -> fixed control (sigma 0, as DBAT
  holds them); ``<filter id="..">keep|remove</filter>`` applied; check points -> role check
  (coordinates kept, not used in the adjustment).
* exterior orientation: the script's ``<prior_eo>`` file (``format`` with id, x, y, z,
  omega, phi, kappa; ``units`` radian, degrees or gon) gives the approximations; images
  without one are left NaN and baarda.pipeline finds approximations by space resection and
  intersection (bundle/resection.py), as DBAT's own script does.
* datum: the control, or DBAT's ``set_datum depend`` (dependent relative orientation, a free
  network held as DBAT holds it: Settings.free_datum); a script without control and without
  set_datum is a free network.

Other processing operations of the script are not executed.  The camera element is read by
io/dbat_camera.py.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from baarda.block.camera import INPUT_CALIBRATION
from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.errors import ProjectError
from baarda.io.dbat_camera import (
    calibrated_camera,
    parse_camera,
    read_dbat_camera,
    read_dbat_cameras,
)
from baarda.io.dbat_operations import initial_camera, read_operations
from baarda.io.records import Records, first_appearance, parse_number, refuse_repeats
from baarda.io.xmltree import Node, parse_xml

KNOWN_FIELDS = {"id", "label", "name", "x", "y", "z", "sx", "sy", "sz", "sxyz", "im", "sxy",
                "path"}


def is_dbat_script(path: str | Path) -> bool:
    p = Path(path)
    if not (p.is_file() and p.suffix.lower() == ".xml"):
        return False
    with open(p, "rb") as f:
        head = f.read(4000).decode("utf-8", "replace")
    return "dbat_script_version" in head


def _fields(node: Node, path: str) -> list[str]:
    fmt = node.attrib.get("format")
    if not fmt:
        raise ProjectError(path, f"<{node.tag}> element without a format attribute", node.line,
                           "format")
    fields = [f.strip() for f in fmt.split(",")]
    bad = [f for f in fields if f not in KNOWN_FIELDS]
    if bad:
        raise ProjectError(path, f"unknown field '{bad[0]}' in format '{fmt}'", node.line,
                           "format")
    return fields


def _resolve(base: Path, text: str, xml_dir: Path) -> Path:
    text = text.strip().replace("$HERE", str(xml_dir))
    p = Path(text)
    return p if p.is_absolute() else base / p


def _base_dir(node: Node, xml_dir: Path, attr: str = "base_dir") -> Path:
    b = node.attrib.get(attr, "$HERE").replace("$HERE", str(xml_dir))
    return Path(b) if Path(b).is_absolute() else xml_dir / b


def _filter_ids(section: Node, path: str) -> tuple[set[str] | None, bool]:
    """(ids, keep) of a <filter id="a,b">keep|remove</filter> element, or (None, True)."""
    f = section.find("filter")
    if f is None:
        return None, True
    action = f.text.strip().lower()
    if action not in ("keep", "remove"):
        raise ProjectError(path, f"filter action '{action}' must be keep or remove", f.line)
    ids = {s.strip() for s in re.split(r"[,\s]+", f.attrib.get("id", "")) if s.strip()}
    return ids, action == "keep"


def _points(section: Node, base: Path, xml_dir: Path, path: str):
    """Rows (id, label, xyz, sigma) of the <file> elements of a ctrl_pts/check_pts section."""
    ids, xyz, sig = [], [], []
    where: list[tuple[str, int]] = []
    flt, keep = _filter_ids(section, path)
    for f in section.findall("file"):
        fields = _fields(f, path)
        for need in ("id", "x", "y", "z"):
            if need not in fields:
                raise ProjectError(path, f"point file format lacks '{need}'", f.line, "format")
        r = Records(_resolve(base, f.text, xml_dir), fields, whole=True)
        pid = r.text("id")
        c = np.column_stack([r.numbers(k) for k in "xyz"])
        if "sxyz" in fields:
            s = np.repeat(r.numbers("sxyz")[:, None], 3, axis=1)
        elif all(k in fields for k in ("sx", "sy", "sz")):
            s = np.column_stack([r.numbers(k) for k in ("sx", "sy", "sz")])
        else:
            s = np.zeros((len(r), 3))
        bad = np.flatnonzero((s < 0).any(axis=1))
        if len(bad):
            raise ProjectError(r.path, "negative standard deviation", int(r.lines[bad[0]]))
        sel = np.ones(len(pid), bool) if flt is None else np.isin(pid, list(flt)) == keep
        ids += list(pid[sel])
        where += [(r.path, int(n)) for n in r.lines[sel]]
        xyz.append(c[sel])
        sig.append(s[sel])
    refuse_repeats(ids, where, lambda i: f"point '{ids[i]}'", "id")  # as --control does
    if not ids:
        return [], np.zeros((0, 3)), np.zeros((0, 3))
    return ids, np.vstack(xyz), np.vstack(sig)


def read_dbat_stations(path: str | Path) -> dict[str, np.ndarray]:
    """EO by image id from a DBAT ``camera_stations.txt`` listing: X, Y, Z [m], angles [rad].

    DBAT 0.9.2.0 writes 'Unit: degrees' in the header but the angles are radians (checked
    against the residual listing of the camcal project, tests/io/test_dbat.py).
    """
    fields = ["no", "id", "x", "y", "z", "omega", "phi", "kappa", "sx", "sy", "sz", "so",
              "sp", "sk", "label"]
    r = Records(path, fields, min_fields=8)
    eo = np.column_stack([r.numbers(k) for k in ("x", "y", "z", "omega", "phi", "kappa")])
    return dict(zip(r.text("id"), eo, strict=True))


ANGLE_UNITS = {"radian": 1.0, "radians": 1.0, "degrees": np.pi / 180, "degree": np.pi / 180,
               "gon": np.pi / 200}
EO_FIELDS = {"id", "label", "ignored", "x", "y", "z", "omega", "phi", "kappa", "sx", "sy",
             "sz", "sxy", "sxyz", "so", "sp", "sk", "sang"}


def _prior_eo(node: Node, base: Path, xml_dir: Path, path: str,
              image_ids: list[str]) -> tuple[np.ndarray, list[str]]:
    """The prior orientations of <input><prior_eo><file format=".." units="..">: (n, 6) EO
    in the order of the images (NaN for an image the file does not list) and notes."""
    f = node.find("file")
    if f is None:
        raise ProjectError(path, "<prior_eo> without a <file>", node.line, "prior_eo")
    fmt = f.attrib.get("format")
    if not fmt:
        raise ProjectError(path, "<file> of <prior_eo> without a format attribute", f.line,
                           "format")
    fields = [x.strip() for x in fmt.split(",")]
    bad = [x for x in fields if x not in EO_FIELDS]
    if bad or "id" not in fields:
        raise ProjectError(path, f"prior_eo format '{fmt}': " + (
            f"unknown field '{bad[0]}'" if bad else "no 'id'"), f.line, "format")
    names = [x if x != "ignored" else f"ignored{i}" for i, x in enumerate(fields)]
    r = Records(_resolve(base, f.text, xml_dir), names, whole=True)
    eo = np.full((len(r), 6), np.nan)
    for k, name in enumerate(("x", "y", "z", "omega", "phi", "kappa")):
        if name in fields:
            eo[:, k] = r.numbers(name)
    notes = []
    if any(a in fields for a in ("omega", "phi", "kappa")):
        unit = f.attrib.get("units")
        if unit not in ANGLE_UNITS:
            raise ProjectError(path, f"prior_eo angles without a known unit (units="
                               f"\"{unit or ''}\"; expected radian, degrees or gon), as "
                               "DBAT requires", f.line, "units")
        eo[:, 3:] *= ANGLE_UNITS[unit]
    if set(fields) & {"sx", "sy", "sz", "sxy", "sxyz", "so", "sp", "sk", "sang"}:
        notes.append(f"{Path(r.path).name}: the prior orientations' standard deviations are "
                     "not read (the prior EO are approximations only)")
    index = {s: i for i, s in enumerate(image_ids)}
    out = np.full((len(image_ids), 6), np.nan)
    for i, s in enumerate(r.text("id")):
        if s not in index:
            raise ProjectError(r.path, f"unknown image id '{s}'", int(r.lines[i]), "id")
        out[index[s]] = eo[i]
    partial = np.isfinite(out).any(axis=1) & ~np.isfinite(out).all(axis=1)
    if partial.any():
        raise ProjectError(r.path, "prior_eo must give all six orientation values (x, y, z, "
                           "omega, phi, kappa)", f.line, "format")
    missing = int((~np.isfinite(out).all(axis=1)).sum())
    notes.append(f"prior orientations of {len(image_ids) - missing} image(s) from "
                 f"{Path(r.path).name} as approximations" + (
                     f"; {missing} image(s) without one are oriented by space resection"
                     if missing else ""))
    return out, notes


def _script_cameras(inp: Node, base: Path, xml_dir: Path, path: str) -> list[dict]:
    """The cameras of <input><cameras>: <camera> elements, or a DBAT camera <file>."""
    node = inp.find("cameras")
    if node is None:
        raise ProjectError(path, "no <cameras> in <input>", inp.line, "cameras")
    cams = [parse_camera(c, path) for c in node.findall("camera")]
    for f in node.findall("file"):
        cams += read_dbat_cameras(_resolve(base, f.text, xml_dir))
    if not cams:
        raise ProjectError(path, "<cameras> holds neither a <camera> nor a camera <file>",
                           node.line, "cameras")
    ids = [str(c["id"]) for c in cams]
    if len(set(ids)) != len(ids):
        raise ProjectError(path, "camera ids are not unique", node.line, "id")
    if len(cams) > 1:
        raise ProjectError(path, "several cameras: the image-to-camera mapping of DBAT "
                           "scripts is not supported", node.line, "cameras")
    return cams


def read_dbat(path: str | Path, *, camera: str | Path | None = None,
              stations: str | Path | None = None, calibrate: bool = True,
              sigma_px: float | None = None) -> Block:
    """Read a DBAT script project (XML + CSV files) into a Block; see the module docstring.

    camera: a DBAT camera file (e.g. a calibration result) replacing the script's camera
    (taken as it is: the script's initial values are not applied to it).  stations: a
    DBAT camera_stations.txt whose EO become the approximations (else the script's prior
    EO, or NaN: baarda.pipeline orients the photos by space resection).  calibrate: when
    the script estimates the interior orientation, estimate it too (the camera as DBAT's
    model 3, `dbat3`); False holds the camera as given.  sigma_px: the image sigma [px]
    of every observation instead of the script's (mm with the pixel height, as DBAT).
    """
    path = Path(path)
    spath = str(path)
    root = parse_xml(path)
    if root.tag != "document" or "dbat_script_version" not in root.attrib:
        raise ProjectError(spath, "not a DBAT script (<document dbat_script_version=..>)",
                           root.line)
    xml_dir = path.parent.resolve()
    inp = root.find("input")
    if inp is None:
        raise ProjectError(spath, "no <input> section", root.line)
    base = _base_dir(inp, xml_dir)
    notes: list[str] = []
    meta = root.find("meta")
    name = (meta.value("name") if meta is not None else None) or path.stem

    # images
    im_node = inp.find("images")
    if im_node is None or im_node.find("file") is None:
        raise ProjectError(spath, "no <images><file> in <input>", inp.line)
    img_ids, img_names, img_files = [], [], []
    img_paths: list[str] = []  # the image files as the script names them
    for f in im_node.findall("file"):
        fields = _fields(f, spath)
        r = Records(_resolve(base, f.text, xml_dir), fields, whole=True)
        img_files.append(Path(r.path).name)
        img_ids += list(r.text("id"))
        img_paths += [s.replace("\\", "/") for s in r.text("path")] if "path" in fields \
            else [""] * (len(img_ids) - len(img_paths))
        img_names += [Path(s.replace("\\", "/")).stem for s in
                      (r.text("path") if "path" in fields else r.text("id"))]
    if len(set(img_ids)) != len(img_ids):
        raise ProjectError(spath, "image ids are not unique", im_node.line)
    photo_ids = img_names if len(set(img_names)) == len(img_names) else list(img_ids)
    photo_of = {s: i for i, s in enumerate(img_ids)}

    # camera and operations
    if camera is not None:
        cam = read_dbat_camera(camera)
        notes.append(f"camera replaced by {Path(camera).name}")
    else:
        cam = _script_cameras(inp, base, xml_dir, spath)[0]
    ops = read_operations(root.find("operations"), spath, cam["n_k"], cam["n_p"],
                          len(img_ids))
    if camera is None:
        cam = initial_camera(cam, ops.initial_io, spath)

    # control and check points
    ctrl = inp.find("ctrl_pts")
    c_ids, c_xyz, c_sig = _points(ctrl, base, xml_dir, spath) if ctrl is not None else \
        ([], np.zeros((0, 3)), np.zeros((0, 3)))
    chk = inp.find("check_pts")
    h_ids, h_xyz, _ = _points(chk, base, xml_dir, spath) if chk is not None else \
        ([], np.zeros((0, 3)), np.zeros((0, 3)))
    fixed = (c_sig == 0)
    if fixed.any():
        notes.append(f"{int(fixed.any(axis=1).sum())} control point(s) without standard "
                     "deviation: fixed, as in DBAT")

    # image measurements
    ip_node = inp.find("image_pts")
    if ip_node is None or ip_node.find("file") is None:
        raise ProjectError(spath, "no <image_pts><file> in <input>", inp.line)
    free = (ops.estimated or ()) if calibrate else ()
    if free:
        cam = calibrated_camera(cam)
        notes.append("camera model 'dbat3' (DBAT's model 3, the model of the script's "
                     "self-calibration)")
        notes.append(INPUT_CALIBRATION + "the script estimates the interior orientation ("
                     + ", ".join(free) + "): estimated")
    rows_photo, rows_point, rows_xy, rows_sig = [], [], [], []
    rows_where: list[tuple[str, int]] = []  # (file, line) of each measurement
    for f in ip_node.findall("file"):
        fields = _fields(f, spath)
        for need in ("id", "im", "x", "y"):
            if need not in fields:
                raise ProjectError(spath, f"image point format lacks '{need}'", f.line,
                                   "format")
        r = Records(_resolve(base, f.text, xml_dir), fields, whole=True)
        if sigma_px is not None:
            s = np.full(len(r), float(sigma_px))
        elif "sxy" in f.attrib:
            s = np.full(len(r), parse_number(f.attrib["sxy"], spath, f.line, "sxy"))
        elif "sxy" in fields:
            s = r.numbers("sxy")
        else:
            s = np.ones(len(r))
        bad = np.flatnonzero(~(s > 0))
        if len(bad):
            raise ProjectError(r.path, "standard deviation must be positive",
                               int(r.lines[bad[0]]), "sxy")
        ims = r.text("im")
        for i, s_im in enumerate(ims):
            if s_im not in photo_of:
                raise ProjectError(r.path, f"unknown image id '{s_im}' (the image list "
                                   f"{', '.join(img_files)} holds {len(img_ids)}: is it cut "
                                   "short?)", int(r.lines[i]), "im")
        rows_photo.append(np.array([photo_of[s] for s in ims], dtype=np.int64))
        rows_point += list(r.text("id"))
        rows_where += [(r.path, int(n)) for n in r.lines]
        x, y = r.numbers("x"), r.numbers("y")
        rows_xy.append(np.column_stack([(x - cam["size_px"][0] / 2) * cam["px"],
                                        (cam["size_px"][1] / 2 - y) * cam["py"]]))
        rows_sig.append(s * cam["py"])
    photo = np.concatenate(rows_photo)
    if not len(photo):
        raise ProjectError(spath, "no image measurements in the <image_pts> files",
                           ip_node.line)
    xy = np.vstack(rows_xy)
    sig = np.concatenate(rows_sig)
    if sigma_px is not None:
        notes.append(f"image sigma {sigma_px:g} px for every observation (given), "
                     f"{sigma_px * cam['py'] * 1e3:.4g} µm with the pixel height")

    # every point: control, check, then the rest in order of appearance
    ids, index = first_appearance(list(c_ids) + list(h_ids) + rows_point)
    k = len(ids)
    pxyz = np.full((k, 3), np.nan)
    psig = np.full((k, 3), np.nan)
    role = np.full(k, "tie", dtype=object)
    for pid, c, s in zip(c_ids, c_xyz, c_sig, strict=True):
        j = index[pid]
        pxyz[j], psig[j], role[j] = c, s, "control"
    for pid, c in zip(h_ids, h_xyz, strict=True):
        j = index[pid]
        pxyz[j], psig[j], role[j] = c, np.nan, "check"
    point = np.array([index[s] for s in rows_point], dtype=np.int64)
    refuse_repeats((photo * k + point).tolist(), rows_where,
                   lambda i: f"point '{rows_point[i]}' on image '{img_ids[photo[i]]}'", "id")

    settings = Settings(name=name, angle_unit="deg", sigma_image_um=float(np.median(sig)) * 1e3,
                        sigma_control_m=tuple(float(v) for v in (np.nanmedian(psig, axis=0)  # type: ignore[arg-type]
                                              if np.isfinite(psig).any() else (0.05,) * 3)))
    if ops.datum is not None:
        ref, rule = ops.datum
        settings.datum = "free"
        settings.free_datum = (photo_ids[ref], rule)
        notes.append(f"datum: dependent relative orientation as the script sets it (image "
                     f"{img_ids[ref]} held, base: {rule})")
    elif not len(c_ids):
        settings.datum = "free"
        notes.append("no control points and no set_datum: a free network")
    cameras = Cameras([str(cam["id"])], np.array([cam["c"]]), cam["pp"][None, :],
                      np.array([cam["kind"]], dtype=object), np.array([cam["coef"]], float),
                      None, pixel_mm=np.array([cam["py"]]),
                      pixel_frame=np.array([[np.nan, np.nan, cam["px"], cam["py"]]]))
    settings.calibration_free = (free,) if free else None
    eo = np.full((len(photo_ids), 6), np.nan)
    prior = inp.find("prior_eo")
    if prior is not None and stations is None:
        eo, more = _prior_eo(prior, base, xml_dir, spath, img_ids)
        notes += more
    photos = Photos(photo_ids, np.zeros(len(photo_ids), np.int64),
                    np.full(len(photo_ids), "", dtype=object), eo, img_paths)
    image = ImagePoints(photo, point, xy, sig)
    points = GroundPoints(ids, pxyz, psig, role)
    if not free and ops.estimated:
        notes.append("the script estimates the interior orientation (self-calibration); "
                     "baarda holds it fixed at the given values")
    notes.append(f"DBAT script {path.name}: pixel size {cam['px']:.6g} x {cam['py']:.6g} mm, "
                 "image origin moved to the image centre, y up")
    block = Block(settings, cameras, photos, image, points, source=spath, notes=notes)
    if stations is not None:
        st = read_dbat_stations(stations)
        missing = [s for s in img_ids if s not in st]
        if missing:
            raise ProjectError(str(stations), f"no station for image id '{missing[0]}'")
        block.photos.eo = np.array([st[s] for s in img_ids])
    return block
