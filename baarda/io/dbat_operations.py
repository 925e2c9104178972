"""The operations of a DBAT script that define the bundle (io/dbat.py), as DBAT 0.9.2
applies them, in document order:

* ``set_bundle_estimate_params`` / ``io``: which interior orientation parameters are
  estimated.  ``<io>true|false</io>`` or elements ``all``, ``cc``, ``pp``, ``px``, ``py``,
  ``aspect``, ``skew``, ``K``, ``P``, ``K1``..``K3``, ``P1``, ``P2`` (true or false), each
  applied after the previous one as DBAT's setcamest does: ``all`` is every parameter
  (aspect and skew included), ``Kn`` true frees K1..Kn and false fixes Kn..K(nK), ``P1`` and
  ``P2`` free or fix both P.  baarda's names (model ``dbat3``): c, x0, y0, b1 (aspect),
  b2 (skew), k1..k3, p1, p2.
* ``set_initial_values`` / ``io``: the start values of the camera, ``loaded`` (the camera
  as given) or ``default`` (camera constant = focal length, principal point at the sensor
  centre, no distortion), for ``all`` or ``cc``, ``pp``, ``K``, ``P``, ``aspect``, ``skew``
  (also a number or a comma list); they matter for the parameters that are not estimated.
  ``eo`` ``loaded``: the prior orientations (``<input><prior_eo>``) are the approximations.
* ``set_datum`` ``depend`` (``ref_cam``, ``ref_base`` longest, x, y or z): dependent
  relative orientation, the datum of a free network (bundle/free_network.py): the six
  orientation unknowns of image ``ref_cam`` held, and one coordinate of the projection
  centre with the largest offset from it (DBAT's rule: the largest signed difference).

Other operations (check_ray_count, spatial_resection, forward_intersection,
bundle_adjustment, estimate flags of eo and op) are what baarda does anyway or are not
read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.errors import ProjectError
from baarda.io.dbat_camera import default_values, with_values
from baarda.io.records import numbers_in, parse_number
from baarda.io.xmltree import Node

ORDER = ("c", "x0", "y0", "b1", "b2", "k1", "k2", "k3", "p1", "p2")
DATUM_BASES = ("longest", "x", "y", "z")


@dataclass(frozen=True)
class Operations:
    """What the operations of a script set: the estimated parameters (baarda's names, in
    ORDER; None: no set_bundle_estimate_params with an <io>), the initial values of the
    camera (element, text, line) and the datum (reference image index, base) or None."""
    estimated: tuple[str, ...] | None
    initial_io: tuple[tuple[str, str, int], ...]
    datum: tuple[int, str] | None


def _bool(node: Node, path: str) -> bool:
    text = node.text.strip()
    if text not in ("true", "false"):
        raise ProjectError(path, f"<{node.tag}>{text}</{node.tag}>: expected true or false",
                           node.line, node.tag)
    return text == "true"


def _estimate_io(io: Node, state: dict[str, bool], n_k: int, n_p: int, path: str) -> None:
    """Apply one <io> element of set_bundle_estimate_params to `state` (name -> estimated)."""
    ks = [f"k{i + 1}" for i in range(n_k)]
    ps = [f"p{i + 1}" for i in range(n_p)]
    simple = {"cc": ["c"], "pp": ["x0", "y0"], "px": ["x0"], "py": ["y0"],
              "aspect": ["b1"], "skew": ["b2"], "K": ks, "P": ps,
              "all": ["c", "x0", "y0", "b1", "b2", *ks, *ps]}
    items = list(io.children)
    if not items:  # <io>true</io>
        items = [Node("all", {}, io.line, text=io.text)]
    for node in items:
        if node.tag == "c":  # a comment
            continue
        on = _bool(node, path)
        if node.tag in simple:
            names = simple[node.tag]
        elif node.tag[:1] in "KP" and node.tag[1:].isdigit():
            n, group = int(node.tag[1:]), ks if node.tag[0] == "K" else ps
            if not 1 <= n <= len(group):
                raise ProjectError(path, f"<{node.tag}>: the camera has {len(group)} "
                                   f"{node.tag[0]} coefficient(s)", node.line, node.tag)
            if node.tag[0] == "P":  # DBAT frees or fixes P1 and P2 together
                n = (max(n, 2) if on else (1 if n == 2 else n))
                n = min(n, len(group))
            names = group[:n] if on else group[n - 1:]
        else:
            raise ProjectError(path, f"<{node.tag}> in set_bundle_estimate_params/io: "
                               "expected all, cc, pp, px, py, aspect, skew, K, P, K1..K3, P1 "
                               "or P2", node.line, node.tag)
        for name in names:
            state[name] = on


def read_operations(ops: Node | None, path: str, n_k: int, n_p: int,
                    n_images: int) -> Operations:
    """The operations of a script (module docstring); ProjectError naming the line of an
    element that DBAT would refuse."""
    state: dict[str, bool] = {}
    asked = False
    initial: list[tuple[str, str, int]] = []
    datum = None
    for op in ([] if ops is None else ops.findall("operation")):
        sbe = op.find("set_bundle_estimate_params")
        io = None if sbe is None else sbe.find("io")
        if io is not None:
            asked = True
            _estimate_io(io, state, n_k, n_p, path)
        siv = op.find("set_initial_values")
        io = None if siv is None else siv.find("io")
        if io is not None:
            items = [c for c in io.children if c.tag != "c"] or \
                [Node("all", {}, io.line, text=io.text)]
            initial += [(c.tag, c.text.strip(), c.line) for c in items]
        sd = op.find("set_datum")
        if sd is not None:
            datum = _datum(sd, path, n_images)
    estimated = tuple(n for n in ORDER if state.get(n)) if asked else None
    return Operations(estimated, tuple(initial), datum)


def _datum(node: Node, path: str, n_images: int) -> tuple[int, str]:
    kind = node.text.strip()
    if kind != "depend":
        raise ProjectError(path, f"set_datum '{kind}': only 'depend' (dependent relative "
                           "orientation) is known", node.line, "set_datum")
    ref = node.attrib.get("ref_cam", "1")
    try:
        cam = int(ref)
    except ValueError:
        cam = 0
    if not 1 <= cam <= n_images:
        raise ProjectError(path, f"set_datum ref_cam '{ref}': expected an image number 1.."
                           f"{n_images}", node.line, "ref_cam")
    base = node.attrib.get("ref_base", "longest")
    if base not in DATUM_BASES:
        raise ProjectError(path, f"set_datum ref_base '{base}': expected longest, x, y or z",
                           node.line, "ref_base")
    return cam - 1, base


def initial_camera(cam: dict, initial: tuple[tuple[str, str, int], ...], path: str) -> dict:
    """The camera with a script's set_initial_values/io applied (module docstring)."""
    defaults = default_values(cam)
    keys = {"cc": ("cc",), "pp": ("pp_dbat",), "K": ("k",), "P": ("p",),
            "aspect": ("aspect",), "skew": ("skew",),
            "all": ("cc", "pp_dbat", "k", "p", "aspect", "skew")}
    for tag, text, line in initial:
        if tag not in keys:
            raise ProjectError(path, f"<{tag}> in set_initial_values/io: expected all, cc, "
                               "pp, K, P, aspect or skew", line, tag)
        if text == "loaded":
            continue
        if text == "default" or (text == "focal" and tag == "cc"):
            cam = with_values(cam, **{k: defaults[k] for k in keys[tag]})
            continue
        if tag == "all":
            raise ProjectError(path, f"<all>{text}</all>: expected loaded or default", line,
                               tag)
        count = {"cc": 1, "pp": 2, "K": cam["n_k"], "P": cam["n_p"], "aspect": 1,
                 "skew": 1}[tag]
        values = numbers_in(text, path, line, tag, count)
        if tag == "pp":
            cam = with_values(cam, pp_dbat=np.array(values))
        elif tag in ("K", "P"):
            width = 3 if tag == "K" else 2
            cam = with_values(cam, **{tag.lower(): (values + [0.0] * width)[:width]})
        else:
            key = keys[tag][0]
            cam = with_values(cam, **{key: parse_number(text, path, line, tag)})
    return cam
