"""A Metashape sensor (``<sensor>``) and its calibration as a baarda camera, and the XML
value helpers of the Metashape readers (io/metashape_chunk.py has the conventions).

Metashape's frame camera model (its manual, appendix "Camera models"): x = X/Z, y = Y/Z
(camera looks down +z, y down), x' = x (1 + K1 r^2 + K2 r^4 + K3 r^6 + K4 r^8) + P1 (r^2 +
2x^2) + 2 P2 x y, y' likewise with P2 (r^2 + 2y^2) + 2 P1 x y; u = w/2 + cx + x' (f + b1) +
y' b2, v = h/2 + cy + y' f [px].  In baarda (y up, origin at the image centre, mm):
``brown_forward`` with c = (f + b1) p, principal point (cx p, -cy p), k1..k3, p1 = P1, p2 =
-P2 (OpenCV's (p1, p2) are Metashape's (P2, P1)), the aspect a = f / (f + b1) - 1.
PhotoScan up to 1.3 writes ``fx``, ``fy`` and an absolute ``cx``, ``cy``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.errors import ProjectError
from baarda.io.xmltree import Node

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


def flag(node: Node, name: str, default: bool = True) -> bool:
    return node.attrib.get(name, "true" if default else "false").lower() in ("true", "1")


def properties(node: Node) -> dict[str, str]:
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
    props = properties(s)
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
