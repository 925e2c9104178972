"""The camera of a DBAT script or camera file (io/dbat.py's text gives the conventions):
sensor, image size, camera constant, principal point and DBAT's lens model 3 in baarda's
image frame, and the camera as baarda's `dbat3` model in DBAT's own frame for
self-calibration.

A camera is a dict: the values as DBAT holds them (`focal`, `cc` [mm], `pp_dbat` [mm from
the upper-left sensor corner, y down], `k`, `p`, `aspect`, `skew`, sensor and image size,
`n_k`, `n_p`) and what baarda's frame needs, derived from them by `_framed` (`c`, `pp`,
`px`, `py`, `kind`, `coef`).  `with_values` changes values (a script's set_initial_values)
and derives the rest again.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.camera_models import principal_point_from_dbat
from baarda.errors import ProjectError
from baarda.io.records import numbers_in, parse_number
from baarda.io.xmltree import Node, parse_xml


def parse_camera(node: Node, path: str) -> dict:
    """A <camera> element of a DBAT script or camera file: the camera in baarda's image
    frame (module docstring of io/dbat.py) and what DBAT's own frame needs."""
    def val(tag):
        c = node.find(tag)
        if c is None:
            raise ProjectError(path, f"camera lacks <{tag}>", node.line, tag)
        return c.text.strip(), c.line

    unit = (node.value("unit") or "mm").strip()
    if unit != "mm":
        raise ProjectError(path, f"camera unit '{unit}': only mm is supported", node.line,
                           "unit")
    text, line = val("image")
    iw, ih = numbers_in(text, path, line, "image", 2)
    if not (iw > 0 and ih > 0):
        raise ProjectError(path, f"image size '{text}' must be positive pixels", line, "image")
    aspect = parse_number(node.value("aspect", "1"), path, node.line, "aspect")
    text, line = val("sensor")
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2:
        raise ProjectError(path, f"sensor '{text}' must be 'width,height'", line, "sensor")
    if parts[0] == "auto" and parts[1] == "auto":
        raise ProjectError(path, "sensor width and height cannot both be auto", line, "sensor")
    if parts[0] == "auto":
        sh = parse_number(parts[1], path, line, "sensor")
        sw = iw * (sh / ih) / aspect
    elif parts[1] == "auto":
        sw = parse_number(parts[0], path, line, "sensor")
        sh = ih * (sw / iw) * aspect
    else:
        sw, sh = (parse_number(p, path, line, "sensor") for p in parts)
    focal_text = node.value("focal")
    cc_text = node.value("cc") or focal_text
    if cc_text is None:
        raise ProjectError(path, "camera lacks <cc> and <focal>", node.line, "cc")
    cc = numbers_in(cc_text, path, node.line, "cc")
    if len(cc) not in (1, 2) or (len(cc) == 2 and cc[0] == 0):
        cc = numbers_in(focal_text or "", path, node.line, "focal", 1)
    focal = numbers_in(focal_text, path, node.line, "focal", 1)[0] if focal_text else cc[0]
    pp = numbers_in(node.value("pp", f"{sw / 2},{sh / 2}"), path, node.line, "pp", 2)
    if pp == [0.0, 0.0] and node.value("pp") is not None and node.find("calibrated") is None:
        pp = [sw / 2, sh / 2]  # DBAT's uncalibrated template: pp = 0 means 'default'
    k = numbers_in(node.value("K", "0,0,0"), path, node.line, "K")
    p = numbers_in(node.value("P", "0,0"), path, node.line, "P")
    if len(k) > 3 or len(p) > 2:
        raise ProjectError(path, "at most 3 K and 2 P coefficients are supported", node.line,
                           "K")
    skew = parse_number(node.value("skew", "0"), path, node.line, "skew")
    model = int(parse_number(node.value("model", "3"), path, node.line, "model"))
    if model != 3:
        raise ProjectError(path, f"lens distortion model {model} is not supported (only "
                           "DBAT's backward model 3, verified against DBAT's results)",
                           node.line, "model")
    n_k = int(parse_number(node.value("nK", str(len(k))), path, node.line, "nK"))
    n_p = int(parse_number(node.value("nP", str(len(p))), path, node.line, "nP"))
    if not (0 <= n_k <= 3 and 0 <= n_p <= 2):
        raise ProjectError(path, f"nK {n_k}, nP {n_p}: at most 3 K and 2 P coefficients are "
                           "supported", node.line, "nK")
    cam = {"id": node.value("id") or node.value("name") or "1", "path": path,
           "line": node.line, "size_px": (iw, ih), "sensor": (sw, sh), "focal": focal,
           "cc": cc[0], "pp_dbat": np.array(pp, float), "k": (k + [0.0] * 3)[:3],
           "p": (p + [0.0] * 2)[:2], "aspect": aspect, "skew": skew, "n_k": n_k,
           "n_p": n_p}
    return _framed(cam)


def _framed(cam: dict) -> dict:
    """The camera with what baarda's image frame needs derived from DBAT's values."""
    if cam["skew"] != 0:
        raise ProjectError(cam["path"], "camera skew is not supported", cam["line"], "skew")
    (iw, ih), (sw, sh) = cam["size_px"], cam["sensor"]
    px, py = sw / iw, sh / ih
    coef = [*cam["k"], *cam["p"]]
    pp = cam["pp_dbat"]
    # DBAT scales pixels by the pixel height and applies the aspect (1 + fa = px / py) to x
    # after subtracting pp: the x of pp is in units of the pixel height
    return {**cam, "c": cam["cc"], "pp": np.array([pp[0] * px / py - sw / 2, sh / 2 - pp[1]]),
            "px": px, "py": py, "kind": "brown_backward" if any(coef) else "none",
            "coef": coef}


def with_values(cam: dict, **values) -> dict:
    """The camera with some of DBAT's values changed (cc, pp_dbat, k, p, aspect, skew)."""
    return _framed({**cam, **values})


def default_values(cam: dict) -> dict:
    """DBAT's 'default' initial values of a camera: the camera constant is the focal length,
    the principal point the sensor centre, no distortion, aspect 1, no skew."""
    sw, sh = cam["sensor"]
    return {"cc": cam["focal"], "pp_dbat": np.array([sw / 2, sh / 2]), "k": [0.0] * 3,
            "p": [0.0] * 2, "aspect": 1.0, "skew": 0.0}


def calibrated_camera(cam: dict) -> dict:
    """The camera of a self-calibrating DBAT script as baarda's `dbat3` model in DBAT's own
    frame: pixels scaled by the pixel height in x and y (the aspect is the model's b1 =
    1 - aspect, DBAT's 'as'), the principal point reduced to the image centre, y up."""
    iw, ih = cam["size_px"]
    py = cam["py"]
    b1 = 1.0 - cam["aspect"]
    pp = principal_point_from_dbat(cam["pp_dbat"][None, :], [b1],
                                   np.array([[iw * py, ih * py]]), "dbat3")[0]
    return {**cam, "kind": "dbat3", "coef": [*cam["k"], *cam["p"], b1, cam["skew"]],
            "pp": pp, "px": py}


def read_dbat_cameras(path: str | Path) -> list[dict]:
    """The cameras of a DBAT camera file (``<document dbat_camera_version=..>``)."""
    root = parse_xml(path)
    cams = root.find("cameras")
    if root.tag != "document" or cams is None or cams.find("camera") is None:
        raise ProjectError(str(path), "not a DBAT camera file (<document><cameras><camera>)",
                           root.line)
    return [parse_camera(c, str(path)) for c in cams.findall("camera")]


def read_dbat_camera(path: str | Path) -> dict:
    """The first camera of a DBAT camera file."""
    return read_dbat_cameras(path)[0]
