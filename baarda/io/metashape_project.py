"""Agisoft Metashape / PhotoScan projects: ``.psz`` (one zip) and ``.psx`` (an XML file with
its ``.files`` folder), read as DBAT's loadpsz reads them, with the nested layout of
Metashape 1.4 on as well.

Layouts (each element's ``path`` is relative to the file that names it; "{projectname}" is
the project's stem):

* PhotoScan up to 1.3 (``.psz``): doc.xml holds the chunks whole; the first chunk's first
  frame names ``tracks0.ply``, ``points0.ply`` and ``projections<N>.ply`` beside it;
* Metashape 1.4 on: doc.xml's ``<chunk path="0/chunk.zip"/>``; chunk.zip's doc.xml is the
  chunk, its ``<frame path="0/frame.zip"/>``; frame.zip's doc.xml has the marker
  projections and ``<point_cloud path=...zip>`` (``<tie_points>`` in 2.x), whose doc.xml
  names the PLY files in that zip; ``.psx``: ``<document path="{projectname}.files/
  project.zip"/>`` and the rest in the ``.files`` folder.

Tie points: points.ply (x y z [id], chunk frame; without id the row is the track), a
projections PLY per camera (x y [size] id: pixels, the track id); a track without a point
(not triangulated) is left out with its projections, as DBAT does.  The first chunk is read
(a note names how many there are).  The chunk's conventions: io/metashape_chunk.py.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block
from baarda.errors import ProjectError
from baarda.io.metashape_block import to_block
from baarda.io.metashape_chunk import TiePoints, read_chunk
from baarda.io.ply import read_ply
from baarda.io.text_files import file_head
from baarda.io.xmltree import Node, parse_xml_bytes

MAX_MEMBER = 2 * 2**30  # bytes of one member once unpacked


class _Place:
    """A folder or a zip (possibly inside another) and a directory in it, to read members
    by a path relative to it; `name` shows where in errors ("a.psz!0/chunk.zip!doc.xml")."""

    def __init__(self, name: str, folder: Path | None = None,
                 archive: zipfile.ZipFile | None = None, prefix: str = "",
                 beside: _Place | None = None) -> None:
        self.name, self.folder, self.archive, self.prefix = name, folder, archive, prefix
        self.beside = beside  # where a path not in the archive is: the archive's folder

    def has(self, rel: str) -> bool:
        if self.archive is None:
            return ((self.folder or Path(".")) / rel).is_file()
        return self._key(rel) in self.archive.NameToInfo

    def _key(self, rel: str) -> str:
        parts: list[str] = []
        for p in (self.prefix + rel).replace("\\", "/").split("/"):
            if p in ("", "."):
                continue
            if p == "..":
                if parts:
                    parts.pop()
                continue
            parts.append(p)
        return "/".join(parts)

    def where(self, rel: str) -> str:
        if self.beside is not None and not self.has(rel):
            return self.beside.where(rel)
        return f"{self.name}!{self._key(rel)}" if self.archive is not None else \
            str((self.folder or Path(".")) / rel)

    def read(self, rel: str, what: str, by: str, line: int | None = None) -> bytes:
        if self.archive is None:
            p = (self.folder or Path(".")) / rel
            try:
                return p.read_bytes()
            except OSError as e:
                raise ProjectError(by, f"{what} '{rel}' cannot be read ({e.strerror or e}; "
                                   f"expected at {p})", line) from None
        if self.beside is not None and not self.has(rel):
            return self.beside.read(rel, what, by, line)
        key = self._key(rel)
        try:
            info = self.archive.getinfo(key)
        except KeyError:
            raise ProjectError(by, f"{what} '{rel}' is not in {self.name} (a truncated or "
                               "incomplete project)", line) from None
        if info.file_size > MAX_MEMBER:
            raise ProjectError(self.where(rel), f"{info.file_size} bytes unpacked: too large")
        try:
            return self.archive.read(key)
        except (zipfile.BadZipFile, OSError, EOFError, ValueError) as e:
            raise ProjectError(self.where(rel), f"cannot be unpacked ({e}; a truncated or "
                               "damaged file)") from None

    def child(self, rel: str, by: str, line: int | None) -> tuple[_Place, str]:
        """The place of a file named by a path attribute: inside a zip for ``*.zip`` (then
        its doc.xml is read), else the same place with the file's folder; and the file
        name to read there."""
        d, _, f = rel.replace("\\", "/").rpartition("/")
        if rel.lower().endswith(".zip"):
            data = self.read(rel, "the archive", by, line)
            return _Place(self.where(rel), archive=_zip(data, self.where(rel)),
                          beside=self.at(d)), "doc.xml"
        return self.at(d), f

    def at(self, d: str) -> _Place:
        """This place moved into its folder `d`."""
        if not d:
            return self
        if self.archive is None:
            return _Place(self.name, folder=(self.folder or Path(".")) / d)
        return _Place(self.name, archive=self.archive, prefix=self._key(d) + "/",
                      beside=self.beside.at(d) if self.beside is not None else None)


def _zip(data: bytes | Path, name: str) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(io.BytesIO(data) if isinstance(data, bytes) else data)
    except (zipfile.BadZipFile, OSError, EOFError) as e:
        raise ProjectError(name, f"not a readable zip archive ({e}; a truncated or damaged "
                           "file)") from None


def _doc(place: _Place, rel: str, what: str, by: str, line: int | None = None) -> tuple[
        Node, _Place]:
    """The XML root named by `rel` (a zip: its doc.xml) and the place its paths are
    relative to."""
    p, f = place.child(rel, by, line)
    return parse_xml_bytes(p.read(f, what, by, line), p.where(f)), p


def is_metashape_project(path: str | Path) -> bool:
    p = Path(path)
    if not p.is_file() or p.suffix.lower() not in (".psz", ".psx"):
        return False
    if p.suffix.lower() == ".psx":
        return b"<document" in file_head(p)
    try:
        with zipfile.ZipFile(p) as z:
            return "doc.xml" in z.namelist()
    except (OSError, zipfile.BadZipFile):
        return False


def _root(p: Path) -> tuple[Node, _Place]:
    """The project's document element and the place its paths are relative to."""
    if p.suffix.lower() == ".psz":
        place = _Place(str(p), archive=_zip(p, str(p)))
        return parse_xml_bytes(place.read("doc.xml", "doc.xml", str(p)), place.where(
            "doc.xml")), place
    root = parse_xml_bytes(p.read_bytes(), str(p))
    rel = root.attrib.get("path")
    if root.tag != "document" or not rel:
        raise ProjectError(str(p), "a .psx document element with a path to its project "
                           "(<document path=\"{projectname}.files/project.zip\">) expected",
                           root.line, "path")
    rel = rel.replace("{projectname}", p.stem)
    return _doc(_Place(str(p.parent), folder=p.parent), rel, "the project archive", str(p),
                root.line)


def read_metashape_project(path: str | Path, *, pixel_mm: float = 0.001,
                           sigma_px: float | None = None) -> Block:
    """The Block of the first chunk of a .psz or .psx project (module docstring)."""
    p = Path(path)
    if not p.is_file():
        raise ProjectError(str(p), "file not found")
    doc, place = _root(p)
    where = place.where("doc.xml")
    chunks_node = doc.find("chunks")
    chunks = chunks_node.findall("chunk") if chunks_node is not None else []
    if doc.tag == "chunk":  # a document that is one chunk
        chunks = [doc]
    if not chunks:
        raise ProjectError(where, "no <chunks><chunk> in the document", doc.line, "chunks")
    notes = [f"Metashape project: {len(chunks)} chunks, the first read"] if len(chunks) > 1 \
        else []
    chunk, cplace = chunks[0], place
    if "path" in chunk.attrib and not chunk.children:
        chunk, cplace = _doc(place, chunk.attrib["path"], "the chunk", where, chunk.line)
    cwhere = cplace.where("doc.xml") if cplace is not place else where
    frames = chunk.find("frames")
    frame_nodes = frames.findall("frame") if frames is not None else []
    frame, fplace = (frame_nodes[0], cplace) if frame_nodes else (None, cplace)
    if frame is not None and "path" in frame.attrib and not frame.children:
        frame, fplace = _doc(cplace, frame.attrib["path"], "the frame", cwhere, frame.line)
    fwhere = fplace.where("doc.xml")
    ch = read_chunk(chunk, frame if frame is not None else chunk, cwhere, pixel_mm)
    all_cams = [c.attrib.get("id", "") for c in _all_cameras(chunk)]
    ties = _tie_points(frame, fplace, fwhere) if frame is not None else None
    block = to_block(ch, ties, pixel_mm=pixel_mm, sigma_px=sigma_px, name=p.stem,
                     all_cameras=all_cams)
    block.notes[1:1] = notes
    return block


def _all_cameras(chunk: Node) -> list[Node]:
    from baarda.io.metashape_chunk import _cameras

    return _cameras(chunk)


def _tie_points(frame: Node, place: _Place, where: str) -> TiePoints | None:
    cloud = frame.find("point_cloud") or frame.find("tie_points")
    if cloud is None:
        return None
    if "path" in cloud.attrib and not cloud.children:
        cloud, place = _doc(place, cloud.attrib["path"], "the tie points", where, cloud.line)
        where = place.where("doc.xml")
    pts = cloud.find("points")
    if pts is None or "path" not in pts.attrib:
        return None
    points = read_ply(place.read(pts.attrib["path"], "the points file", where, pts.line),
                      place.where(pts.attrib["path"]))
    for k in ("x", "y", "z"):
        if k not in points:
            raise ProjectError(place.where(pts.attrib["path"]), f"no property {k}")
    n = len(points["x"])
    track = points["id"].astype(np.int64) if "id" in points else np.arange(n)
    if "valid" in points:
        ok = points["valid"] != 0
    else:
        ok = np.ones(n, bool)
    xyz = np.column_stack([points[k] for k in "xyz"]).astype(float)
    if not np.isfinite(xyz[ok]).all():
        raise ProjectError(place.where(pts.attrib["path"]), "coordinates that are not finite")
    track, xyz = track[ok], xyz[ok]
    if len(np.unique(track)) < len(track):
        raise ProjectError(place.where(pts.attrib["path"]), "track ids repeat: one point per "
                           "track expected")
    order = np.argsort(track)
    track, xyz = track[order], xyz[order]
    cams, pidx, uvs = [], [], []
    for pr in cloud.findall("projections"):
        rel = pr.attrib.get("path")
        cid = pr.attrib.get("camera_id")
        if rel is None or cid is None:
            raise ProjectError(where, "<projections> needs camera_id and path", pr.line)
        t = read_ply(place.read(rel, "the projections file", where, pr.line),
                     place.where(rel))
        for k in ("x", "y", "id"):
            if k not in t:
                raise ProjectError(place.where(rel), f"no property {k}")
        tid = t["id"].astype(np.int64)
        pos = np.searchsorted(track, tid)
        found = (pos < len(track)) & (track[np.minimum(pos, len(track) - 1)] == tid)
        cams.extend([cid] * int(found.sum()))
        pidx.append(pos[found])
        uvs.append(np.column_stack([t["x"][found], t["y"][found]]).astype(float))
    ids = [f"t{int(k)}" for k in track]
    return TiePoints(ids, xyz, cams, np.concatenate(pidx) if pidx else np.zeros(0, np.int64),
                     np.vstack(uvs) if uvs else np.zeros((0, 2)), where)


def detect(path: Path) -> bool:
    return is_metashape_project(path)


def read(path: Path, request) -> Block:
    """The registry's entry (io/formats.py)."""
    from baarda.io.image_sigma import PIXEL_MM

    return read_metashape_project(path, pixel_mm=PIXEL_MM if request.pixel_mm is None
                                  else request.pixel_mm, sigma_px=request.sigma_px)
