"""`--gcp-list`: the GCPs of an OpenDroneMap gcp_list.txt (read by io/gcp_list.py) added to a
block as control points measured on its images (block/gcp.py), and the block placed in the
file's CRS by the GCPs it sees (bundle/geometry.py intersects them; block/control.into_frame
carries the block).  On the pipeline's floor: it reads a file and calls a method."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block
from baarda.errors import ProjectError
from baarda.io.text_files import ENCODING


def with_gcp_list(block: Block, path: str | Path, encoding: str = ENCODING,
                  crs: str | None = None) -> Block:
    """The block with the GCPs of an OpenDroneMap gcp_list.txt (io/gcp_list.py) as control
    points measured on its images (block/gcp.py), placed in the file's CRS: the GCPs with
    X, Y, Z and two or more measurements are intersected from the block's orientations (in
    the input's own frame), and the similarity that fits them to the file's coordinates
    (three or more, not on a line; computed in a local east-north-up frame of the CRS,
    pyproj) carries every orientation and point into the CRS, as --control carries an input
    in another frame.  The CRS is the file's first line; `crs` (--crs), an input's own CRS
    or GNSS/IMU observations that differ from it are errors."""
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    from baarda.block.control import into_frame
    from baarda.block.crs import LocalFrame
    from baarda.block.gcp import add_gcps
    from baarda.bundle.geometry import intersect
    from baarda.io.gcp_list import read_gcp_list

    gcps = read_gcp_list(path, encoding)
    try:
        crs_file = CRS.from_user_input(gcps.crs)
    except CRSError as e:
        raise ProjectError(gcps.path, f"the first line {gcps.crs!r} is not a CRS (a PROJ "
                           f"string, EPSG:NNNN or 'WGS84 UTM 32N'): {e}", gcps.crs_line,
                           "crs") from None
    for given, where in ((crs, "--crs"), (block.settings.crs, "the input's CRS")):
        if given and CRS.from_user_input(given) != crs_file:
            raise ProjectError(gcps.path, f"{where} {given} is not the CRS of the GCPs "
                               f"({gcps.crs}): the block is placed in the GCPs' CRS",
                               gcps.crs_line, "crs")
    if len(block.gnss) or len(block.imu):
        raise ProjectError(gcps.path, "the input has GNSS/IMU observations in its own frame: "
                           "GCPs measured on the images are added to blocks without them "
                           "(COLMAP, BAL, Bundler, NVM)")
    k0 = len(block.points)
    block = _sizes_from_images(block, gcps, path)
    block = add_gcps(block, gcps)
    rays = np.flatnonzero(np.bincount(gcps.gcp, minlength=len(gcps)) >= 2)
    with np.errstate(all="ignore"):
        seen = intersect(block, block.photos.eo, k0 + rays) if len(rays) else np.zeros((0, 3))
    pts = block.points
    own_xyz = pts.xyz.copy()
    own_xyz[k0:] = np.nan
    own_xyz[k0 + rays] = seen  # the GCPs in the input's frame, carried along as its points
    full = np.isfinite(gcps.xyz[rays]).all(axis=1) & np.isfinite(seen).all(axis=1)
    given = gcps.xyz[rays[full]]
    frame = LocalFrame(gcps.crs, given.mean(axis=0) if full.any() else np.zeros(3))
    xyz, eo, text = into_frame(own_xyz, block.photos.eo, seen[full], frame.to_local(given))
    if not np.isfinite(eo).all():
        raise ProjectError(gcps.path, f"{int(full.sum())} GCP(s) with X, Y, Z measured on two "
                           "or more images of the block, not on a line: three are needed to "
                           "place the block in the GCPs' CRS")
    known = np.isfinite(xyz).all(axis=1)
    xyz[known] = frame.from_local(xyz[known])
    xyz[k0:] = np.where(np.isfinite(gcps.xyz), gcps.xyz, xyz[k0:])  # a height not given:
    lost = np.flatnonzero(~np.isfinite(xyz[k0:]).all(axis=1))  # the intersection's
    if len(lost):
        k = int(lost[0])
        raise ProjectError(gcps.path, f"GCP {gcps.ids[k]} has no height and is measured on "
                           "one image: its height cannot be approximated (measure it on a "
                           "second image or give geo_z)", int(gcps.first_line[k]), "geo_z")
    eo = frame.eo_from_local(eo)
    notes = list(block.notes) + [f"{gcps.path}: the block placed in {frame.crs.name} by the "
                                 "GCPs: " + text.replace("the control's frame", "the CRS")]
    settings = replace(block.settings, crs=gcps.crs, datum="control", free_datum=None)
    return replace(block, settings=settings, points=replace(pts, xyz=xyz),
                   photos=replace(block.photos, eo=eo), frame=None, notes=notes)


def _sizes_from_images(block: Block, gcps, path: str | Path) -> Block:
    """The block with the image size of its cameras that have none (Bundler, NVM) from the
    image files the GCP list names, looked for beside the GCP list and the input and in
    their images/ folders."""
    from baarda.block.gcp import photo_of_image, with_image_sizes
    from baarda.block.pixels import known_grid
    from baarda.io.gcp_list import image_sizes

    if block.cameras.pixel_frame is None or known_grid(block.cameras).all():
        return block
    src = Path(block.source) if block.source else None
    bases = [Path(path).parent] + ([] if src is None else [src if src.is_dir() else src.parent])
    folders = [f for b in bases for f in (b, b / "images", b.parent / "images")]
    found = image_sizes(gcps.image, folders)
    photo = photo_of_image(block, gcps.image, gcps.path, gcps.line)
    return with_image_sizes(block, photo, [found.get(n) for n in gcps.image])
