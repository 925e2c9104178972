"""The camera of a DBAT script or camera file (io/dbat.py's text gives the conventions):
sensor, image size, camera constant, principal point and DBAT's lens model 3 in baarda's
image frame, the camera as baarda's `dbat3` model in DBAT's own frame for self-calibration,
and which interior orientation parameters a script estimates."""

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
    def val(tag, count=None, default=None):
        c = node.find(tag)
        if c is None:
            if default is None:
                raise ProjectError(path, f"camera lacks <{tag}>", node.line, tag)
            return default
        return c.text.strip(), c.line

    unit = (node.value("unit") or "mm").strip()
    if unit != "mm":
        raise ProjectError(path, f"camera unit '{unit}': only mm is supported", node.line,
                           "unit")
    text, line = val("image")
    iw, ih = numbers_in(text, path, line, "image", 2)
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
    focal = node.value("focal")
    cc_text = node.value("cc") or focal
    if cc_text is None:
        raise ProjectError(path, "camera lacks <cc> and <focal>", node.line, "cc")
    cc = numbers_in(cc_text, path, node.line, "cc")
    if len(cc) not in (1, 2) or (len(cc) == 2 and cc[0] == 0):
        cc = numbers_in(focal or "", path, node.line, "focal", 1)
    pp = numbers_in(node.value("pp", f"{sw / 2},{sh / 2}"), path, node.line, "pp", 2)
    if pp == [0.0, 0.0] and node.value("pp") is not None and node.find("calibrated") is None:
        pp = [sw / 2, sh / 2]  # DBAT's uncalibrated template: pp = 0 means 'default'
    k = numbers_in(node.value("K", "0,0,0"), path, node.line, "K")
    p = numbers_in(node.value("P", "0,0"), path, node.line, "P")
    if len(k) > 3 or len(p) > 2:
        raise ProjectError(path, "at most 3 K and 2 P coefficients are supported", node.line,
                           "K")
    k, p = (k + [0.0] * 3)[:3], (p + [0.0] * 2)[:2]
    skew = parse_number(node.value("skew", "0"), path, node.line, "skew")
    if skew != 0:
        raise ProjectError(path, "camera skew is not supported", node.line, "skew")
    model = int(parse_number(node.value("model", "3"), path, node.line, "model"))
    c = cc[0]
    if model != 3:
        raise ProjectError(path, f"lens distortion model {model} is not supported (only "
                           "DBAT's backward model 3, verified against DBAT's results)",
                           node.line, "model")
    kind, coef = "brown_backward", [*k, *p]
    if not any(coef):
        kind = "none"
    px, py = sw / iw, sh / ih
    # DBAT scales pixels by the pixel height and applies the aspect (1 + fa = px / py) to x
    # after subtracting pp: the x of pp is in units of the pixel height
    return {"id": node.value("id") or node.value("name") or "1", "c": c,
            "pp": np.array([pp[0] * px / py - sw / 2, sh / 2 - pp[1]]), "px": px, "py": py,
            "size_px": (iw, ih), "kind": kind, "coef": coef, "k": k, "p": p,
            "aspect": aspect, "pp_dbat": np.array(pp, float), "skew": skew,
            "n_k": int(parse_number(node.value("nK", str(len(k))), path, node.line, "nK")),
            "n_p": int(parse_number(node.value("nP", str(len(p))), path, node.line, "nP"))}


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


def estimated_io(ops: Node | None, n_k: int, n_p: int) -> tuple[str, ...]:
    """The interior orientation that a script's set_bundle_estimate_params estimates, as
    baarda's parameter names of the `dbat3` model (empty: none)."""
    if ops is None:
        return ()
    names: tuple[str, ...] = ()
    for op in ops.findall("operation"):
        sbe = op.find("set_bundle_estimate_params")
        io = None if sbe is None else sbe.find("io")
        if io is None:
            continue
        flags = {c.tag: (c.text or "").strip().lower() == "true" for c in io.children}
        every = flags.get("all", (io.text or "").strip().lower() == "true")
        ks = tuple(f"k{i + 1}" for i in range(n_k))
        ps = tuple(f"p{i + 1}" for i in range(n_p))
        parts = {"cc": ("c",), "pp": ("x0", "y0"), "aspect": ("b1",), "skew": ("b2",),
                 "k": ks, "p": ps}
        chosen = []
        for tag, group in parts.items():
            if flags.get(tag, every and tag != "skew"):
                chosen += list(group)
        names = tuple(chosen)
    return names


def read_dbat_camera(path: str | Path) -> dict:
    """The first camera of a DBAT camera file (``<document dbat_camera_version=..>``)."""
    root = parse_xml(path)
    cams = root.find("cameras")
    if root.tag != "document" or cams is None or cams.find("camera") is None:
        raise ProjectError(str(path), "not a DBAT camera file (<document><cameras><camera>)",
                           root.line)
    return parse_camera(cams.find("camera"), str(path))


def _flat(node: Node) -> str:
    return f"<{node.tag}>" + "".join(_flat(c) for c in node.children)


def _io_flag(ops: Node) -> str:
    out = []
    for op in ops.findall("operation"):
        sbe = op.find("set_bundle_estimate_params")
        if sbe is not None and sbe.find("io") is not None:
            io = sbe.find("io")
            out.append((io.text + " ".join(c.text for c in io.children)).lower())
    return " ".join(out)


def estimates_io(ops: Node) -> bool:
    """Whether a script's operations estimate the interior orientation at all (any
    set_bundle_estimate_params with an <io> that says true)."""
    return "<io>" in _flat(ops) and "true" in _io_flag(ops)
