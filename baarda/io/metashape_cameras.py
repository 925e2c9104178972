"""Agisoft Metashape cameras XML (File > Export > Cameras, "Agisoft XML"): the chunk's
sensors, camera transforms, chunk transform and CRS, markers with their reference and
image projections (conventions: io/metashape_chunk.py).

With only the XML the block is the markers' block.  The tie points join from a Bundler file
of the same chunk (`--tie-points bundle.out`, or a ``bundle.out`` beside the XML): its
cameras are matched to the XML's by image name (list.txt; without it by order), its
coordinates are taken as the chunk frame or the CRS, whichever its camera centres agree
with (else an error), its image coordinates (pixels from the image centre, y up) become
pixels of the image; its own f, k1, k2 are not used (the XML's sensors are the cameras).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block
from baarda.errors import ProjectError
from baarda.io.metashape_block import to_block
from baarda.io.metashape_chunk import TiePoints, _cameras, read_chunk
from baarda.io.text_files import file_head
from baarda.io.xmltree import Node, parse_xml

AGREE = 1e-3  # camera centres of a Bundler file agree with the XML's: relative to the extent


def is_metashape_cameras(path: str | Path) -> bool:
    if Path(path).suffix.lower() != ".xml":
        return False
    head = file_head(path)
    return b"<document" in head and b"<chunk" in head


def _chunk(doc: Node, where: str) -> Node:
    if doc.tag != "document":
        raise ProjectError(where, f"<{doc.tag}>: a Metashape <document> expected", doc.line)
    ch = doc.find("chunk")
    if ch is None and doc.find("chunks") is not None:
        ch = doc.find("chunks").find("chunk")  # type: ignore[union-attr]
    if ch is None:
        raise ProjectError(where, "no <chunk> in the document", doc.line, "chunk")
    return ch


def read_metashape_cameras(path: str | Path, *, pixel_mm: float = 0.001,
                           sigma_px: float | None = None,
                           tie_points: str | Path | None = None) -> Block:
    """The Block of a Metashape cameras XML (module docstring)."""
    p = Path(path)
    if not p.is_file():
        raise ProjectError(str(p), "file not found")
    doc = parse_xml(p)
    chunk = _chunk(doc, str(p))
    frames = chunk.find("frames")
    frame = frames.find("frame") if frames is not None else None
    ch = read_chunk(chunk, frame if frame is not None else chunk, str(p), pixel_mm)
    cams = _cameras(chunk)
    all_cams = [c.attrib.get("id", "") for c in cams]
    all_labels = [c.attrib.get("label", "") for c in cams]
    if tie_points is None and (p.parent / "bundle.out").is_file():
        tie_points = p.parent / "bundle.out"
    ties = None if tie_points is None else _bundler_ties(Path(tie_points), ch, all_cams,
                                                         all_labels)
    return to_block(ch, ties, pixel_mm=pixel_mm, sigma_px=sigma_px, name=p.stem,
                    all_cameras=all_cams)


def _bundler_ties(path: Path, ch, all_cams: list[str], all_labels: list[str]) -> TiePoints:
    from baarda.io.bundler import bundle_file, read_bundler

    b = read_bundler(path, pixel_mm=1.0, sigma_px=1.0)  # pixels
    src = str(bundle_file(path))
    stems: dict[str, int] = {}
    for k, s in enumerate(all_labels):
        stems.setdefault(Path(s).stem, k)
    has_list = b.photos.image is not None  # bundler names the images only from list.txt
    ids = []
    for name in b.photos.ids:
        if has_list:
            k = stems.get(Path(name).stem, -1)
        else:
            k = int(name) if name.isdigit() and int(name) < len(all_cams) else -1
        if k < 0:
            more = ", ..." if len(all_labels) > 5 else ""
            raise ProjectError(src, f"image {name} is not a camera of the chunk (its labels: "
                               f"{', '.join(all_labels[:5])}{more})")
        ids.append(all_cams[k])
    # the frame of the Bundler file: the chunk frame or the CRS (by the camera centres)
    index = {c: i for i, c in enumerate(ch.camera_ids)}
    common = [(j, index[c]) for j, c in enumerate(ids) if c in index]
    if len(common) < 2:
        raise ProjectError(src, "fewer than two of its cameras are aligned cameras of the "
                           "chunk: the tie points cannot be placed")
    jb, ix = np.array(common).T
    centre_b = b.photos.eo[jb, :3]
    local = ch.camera_pose[ix, :3, 3]
    crs = ch.to_crs(local)
    ext_l = float(np.ptp(local, axis=0).max()) or 1.0
    ext_c = float(np.ptp(crs, axis=0).max()) or 1.0
    d_local = float(np.abs(centre_b - local).max()) / ext_l
    d_crs = float(np.abs(centre_b - crs).max()) / ext_c
    if min(d_local, d_crs) > AGREE:
        raise ProjectError(src, "its camera centres agree neither with the chunk frame of the "
                           f"XML nor with its reference system (differences {d_local:.3g} and "
                           f"{d_crs:.3g} of the extent): not the same chunk?")
    sens = [ch.sensors[ch.camera_sensor[index[ids[j]]]] if ids[j] in index else None
            for j in range(len(ids))]
    photo = b.image.photo
    w = np.array([s.width if s else 0 for s in sens], float)[photo]
    h = np.array([s.height if s else 0 for s in sens], float)[photo]
    uv = np.column_stack([b.image.xy_mm[:, 0] + w / 2, h / 2 - b.image.xy_mm[:, 1]])
    cams = [ids[j] for j in photo.tolist()]
    return TiePoints([f"t{k}" for k in b.points.ids], b.points.xyz, cams,
                     b.image.point.astype(np.int64), uv, src, in_crs=d_crs <= d_local)


def detect(path: Path) -> bool:
    return is_metashape_cameras(path)


def read(path: Path, request) -> Block:
    """The registry's entry (io/formats.py)."""
    from baarda.io.image_sigma import PIXEL_MM

    return read_metashape_cameras(path, pixel_mm=PIXEL_MM if request.pixel_mm is None
                                  else request.pixel_mm, sigma_px=request.sigma_px,
                                  tie_points=request.tie_points)
