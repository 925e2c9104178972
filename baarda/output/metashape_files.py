"""Writing a Block as a Metashape cameras XML (cameras.xml) with its tie points in a Bundler
file beside it (bundle.out, list.txt): the inverse of io/metashape_cameras.py (conventions
in io/metashape_chunk.py), read back by it as one block.

* sensors: one per camera; f = c (1 + a) / p, b1 = c / p - f, cx = x0 / p, cy = -y0 / p
  [px], k1..k3, p1 = p1, p2 = -p2 (``brown_forward``; ``none`` writes zeros; another model
  with coefficients is a ValueError), ``fixed`` unless the camera has free parameters; the
  pixel size is the camera's (block/pixels.pixel_sizes), else the nominal 1 µm; the image
  size is the block's where its grid is known, else the smallest even size centred on the
  image origin that holds every observation (noted; block/pixels.image_sizes);
* the chunk transform: rotation I, scale 1, translation the mean projection centre;
  camera transforms [R diag(1, -1, -1) | X0 - t]; a block in a CRS's local frame
  (block.frame) goes out in it, the transform mapping it to earth-centred coordinates (as
  Metashape's does), the markers' references in the CRS and its WKT as <reference>;
* markers: control points (reference with sx, sy, sz, enabled) and check points (enabled
  false), with their projections; tie points go to bundle.out (cameras f = c / p, k1 = k2 =
  0: the XML holds the cameras); accuracy_tiepoints / accuracy_projections: the median image
  sigma of each kind [px] (per-observation sigmas are not held: noted where they differ).
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from baarda.block.camera import lens
from baarda.block.photo_block import Block
from baarda.block.pixels import image_sizes, known_grid, pixel_sizes
from baarda.block.rotation import rotation_matrix
from baarda.io.image_sigma import PIXEL_MM
from baarda.output.atomic import write_text
from baarda.output.block_checks import checked_block

FLIP = np.diag([1.0, -1.0, -1.0])


def _n(v: float) -> str:
    return repr(float(v))


def _sensor(block: Block, i: int, pixel: float, w: int, h: int) -> list[str]:
    cams = block.cameras
    kind, coef = lens(cams, i)
    if kind == "brown_forward":
        k1, k2, k3, p1, p2, a = coef[:6]
    elif kind == "none" or not np.any(coef):
        k1 = k2 = k3 = p1 = p2 = a = 0.0
    else:
        raise ValueError(f"camera {cams.ids[i]}: model {kind} has no place in Metashape's "
                         "(brown_forward or none can be written)")
    c_px = float(cams.focal_mm[i]) / pixel
    f = c_px * (1 + a)
    x0, y0 = (float(v) for v in cams.principal_point_mm[i])
    chosen = block.settings.calibration_free
    free = chosen[i] if chosen is not None else ()
    out = [f'      <sensor id="{i}" label={quoteattr(cams.ids[i])} type="frame">',
           f'        <resolution width="{w}" height="{h}"/>',
           f'        <property name="pixel_width" value="{_n(pixel)}"/>',
           f'        <property name="pixel_height" value="{_n(pixel)}"/>',
           f'        <property name="fixed" value="{"false" if free else "true"}"/>',
           '        <calibration type="frame" class="adjusted">',
           f'          <resolution width="{w}" height="{h}"/>',
           f"          <f>{_n(f)}</f>", f"          <cx>{_n(x0 / pixel)}</cx>",
           f"          <cy>{_n(-y0 / pixel)}</cy>"]
    if a:
        out.append(f"          <b1>{_n(c_px - f)}</b1>")
    for name, v in (("k1", k1), ("k2", k2), ("k3", k3), ("p1", p1), ("p2", -p2)):
        if v or name in free:
            out.append(f"          <{name}>{_n(v)}</{name}>")
    out += ["        </calibration>", "      </sensor>"]
    return out


def write_metashape(block: Block, folder: str | Path, pixel_mm: float = PIXEL_MM) -> list[str]:
    """cameras.xml (and bundle.out, list.txt for the tie points) of `block` in `folder`;
    the notes on what was dropped (module docstring)."""
    notes = checked_block(block, coordinates=True)
    folder = Path(folder)
    im, pts = block.image, block.points
    pxy = pixel_sizes(block.cameras, pixel_mm)
    pixel = pxy[:, 0]
    cam = block.photos.camera[im.photo]
    sizes = [(int(w), int(h)) for w, h in image_sizes(block.cameras, cam, im.xy_mm, pxy)]
    if not known_grid(block.cameras).all():
        notes.append("image size: not in the block for every camera; there the smallest even "
                     "size centred on the image origin that holds the observations is written")
    frame = block.frame
    centre = block.photos.eo[:, :3].mean(axis=0) if frame is None else np.zeros(3)
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', '<document version="1.5.0">',
             f'  <chunk label={quoteattr(block.settings.name)} enabled="true">',
             f'    <sensors next_id="{len(block.cameras)}">']
    for i in range(len(block.cameras)):
        lines += _sensor(block, i, float(pixel[i]), *sizes[i])
    lines += ["    </sensors>", f'    <cameras next_id="{len(block.photos)}" '
              'next_group_id="0">']
    eo = block.photos.eo
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5]) @ FLIP
    for k, pid in enumerate(block.photos.ids):
        m = np.eye(4)
        m[:3, :3] = r[k]
        m[:3, 3] = eo[k, :3] - centre
        lines += [f'      <camera id="{k}" label={quoteattr(pid)} '
                  f'sensor_id="{int(block.photos.camera[k])}" enabled="true">',
                  "        <transform>" + " ".join(_n(v) for v in m.ravel()) + "</transform>",
                  "      </camera>"]
    lines.append("    </cameras>")
    used = np.unique(im.point)
    marked = used[pts.role[used] != "tie"]
    lines.append(f'    <markers next_id="{len(marked)}">')
    ref = pts.xyz if frame is None else frame.from_local(pts.xyz)
    for k, j in enumerate(marked):
        x, y, z = (float(v) for v in ref[j])
        s = pts.sigma[j]
        ctrl = pts.role[j] == "control"
        sig = "".join(f' {a}="{_n(v)}"' for a, v in zip(("sx", "sy", "sz"), s, strict=True)
                      if ctrl and np.isfinite(v) and v > 0)
        lines += [f'      <marker id="{k}" label={quoteattr(pts.ids[j])}>',
                  f'        <reference x="{_n(x)}" y="{_n(y)}" z="{_n(z)}"{sig} '
                  f'enabled="{"true" if ctrl else "false"}"/>', "      </marker>"]
        if ctrl and np.any(s == 0):
            notes.append(f"control point {pts.ids[j]}: a fixed coordinate (sigma 0) has no "
                         "place in Metashape: written without its accuracy (the default)")
    lines.append("    </markers>")
    is_mark = np.isin(im.point, marked)
    sig_px = im.sigma_mm / pixel[cam]
    lines += ['    <frames next_id="1">', '      <frame id="0">', "        <markers>"]
    mk = {int(j): k for k, j in enumerate(marked)}
    rows = np.flatnonzero(is_mark)
    for j in marked:
        sel = rows[im.point[rows] == j]
        lines.append(f'          <marker marker_id="{mk[int(j)]}">')
        for o in sel:
            c = int(cam[o])
            u = im.xy_mm[o, 0] / pixel[c] + sizes[c][0] / 2
            v = sizes[c][1] / 2 - im.xy_mm[o, 1] / pixel[c]
            lines.append(f'            <location camera_id="{int(im.photo[o])}" '
                         f'pinned="true" x="{_n(u)}" y="{_n(v)}"/>')
        lines.append("          </marker>")
    # the chunk frame: the block's, moved by `centre`; in a CRS (block.frame) the transform
    # maps it to earth-centred coordinates, as Metashape's does
    r_t = np.eye(3) if frame is None else frame.rot.T
    t_t = centre if frame is None else frame.origin_ecef
    lines += ["        </markers>", "      </frame>", "    </frames>",
              "    <transform>", "      <rotation>" + " ".join(_n(v) for v in r_t.ravel())
              + "</rotation>",
              "      <translation>" + " ".join(_n(v) for v in t_t) + "</translation>",
              "      <scale>1</scale>", "    </transform>"]
    if frame is not None:
        lines.append(f"    <reference>{frame.crs.to_wkt('WKT1_GDAL')}</reference>")
    elif block.settings.crs:
        notes.append(f"CRS {block.settings.crs}: the block's coordinates are written as they "
                     "are, without a CRS (a chunk in a CRS needs its local frame)")
    settings = []
    for name, sel in (("accuracy_tiepoints", ~is_mark), ("accuracy_projections", is_mark)):
        if sel.any():
            med = float(np.median(sig_px[sel]))
            settings.append(f'      <property name="{name}" value="{_n(med)}"/>')
            if np.ptp(sig_px[sel]) > 1e-9 * med:
                notes.append(f"{name}: one image sigma for all, the median {med:.4g} px "
                             "(the observations' own sigmas are not held)")
    lines += ["    <settings>"] + settings + ["    </settings>", "  </chunk>", "</document>"]
    folder.mkdir(parents=True, exist_ok=True)
    write_text(folder / "cameras.xml", "\n".join(lines) + "\n")
    ties = used[pts.role[used] == "tie"]
    if len(ties):
        _write_ties(block, folder, pixel, ties)
    return notes


def _write_ties(block: Block, folder: Path, pixel, ties) -> None:
    """bundle.out (cameras in the CRS, f = c / p, no distortion; image coordinates in pixels
    from the image origin, y up) and list.txt of the tie points, read by
    io/metashape_cameras.py beside the XML."""
    im = block.image
    eo = block.photos.eo
    rt = np.swapaxes(rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5]), 1, 2)  # world -> camera
    out = ["# Bundle file v0.3", f"{len(block.photos)} {len(ties)}"]
    for k in range(len(block.photos)):
        c = int(block.photos.camera[k])
        out.append(f"{_n(block.cameras.focal_mm[c] / pixel[c])} 0 0")
        out += [" ".join(_n(v) for v in row) for row in rt[k]]
        out.append(" ".join(_n(v) for v in -rt[k] @ eo[k, :3]))
    cam = block.photos.camera[im.photo]
    xy = im.xy_mm / pixel[cam][:, None]
    order = np.argsort(im.point, kind="stable")
    bounds = np.searchsorted(im.point[order], np.arange(len(block.points.ids) + 1))
    for n, j in enumerate(ties):
        sel = order[bounds[j]:bounds[j + 1]]
        out.append(" ".join(_n(v) for v in block.points.xyz[j]))
        out.append("128 128 128")
        out.append(f"{len(sel)} " + " ".join(
            f"{int(im.photo[o])} {n} {_n(xy[o, 0])} {_n(xy[o, 1])}" for o in sel))
    write_text(folder / "bundle.out", "\n".join(out) + "\n")
    write_text(folder / "list.txt", "\n".join(block.photos.ids) + "\n")
