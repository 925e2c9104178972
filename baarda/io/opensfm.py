"""OpenSfM datasets and OpenDroneMap projects (docs/formats.md, docs/odm.md).

An OpenSfM dataset folder holds
* ``reconstruction.json`` (or the example's ``reconstruction_example.json``): a list of
  reconstructions, of which the first (OpenSfM's largest) is read: ``cameras`` (id ->
  projection_type, width, height, focal or focal_x/focal_y, c_x, c_y, k1, k2, k3, p1, p2 in
  OpenSfM's normalised units: pixels / max(width, height)), ``shots`` (rotation: angle-axis
  and translation of the world-to-camera transform x_cam = R X + t, camera x right, y down,
  z forward; gps_position in the topocentric frame, gps_dop in m), ``points`` (id ->
  coordinates), ``reference_lla`` (or ``reference_lla.json``: the origin of the topocentric
  east-north-up frame, WGS84 latitude, longitude, ellipsoidal altitude);
* ``tracks.csv`` (or ``tracks_example.csv``): ``image track feature x y [scale r g b
  [segmentation instance]]``, tab separated, normalised image coordinates (x right, y down,
  origin at the image centre), after an optional ``OPENSFM_TRACKS_VERSION_v*`` line;
* ``ground_control_points.json`` (points with id, position latitude/longitude/altitude and
  observations shot_id/projection) or ODM's ``gcp_list.txt`` (a first line naming the CRS,
  then ``X Y Z px py image [name]`` in that CRS and in pixels of the original image);
* optionally ``camera_models.json`` / ``camera_models_overrides.json`` (cameras missing from
  the reconstruction), ``config.yaml`` (gcp_horizontal_sd, gcp_vertical_sd).

An ODM project folder is read through its ``opensfm/`` subfolder and its ``gcp_list.txt``.

Conventions (checked by reprojection, tests/io/test_opensfm.py):
* image coordinates: x_mm = x_n S p, y_mm = -y_n S p with S = max(width, height) px and p the
  nominal pixel size (mm); pixel coordinates of gcp_list.txt: x_n = (px + 0.5 - w/2) / S;
* cameras: c = focal S p (brown: focal_x; aspect a = focal_y / focal_x - 1), principal point
  (c_x S p, -c_y S p); the distortion is OpenCV's Brown model on x/z, y/z, which is baarda's
  ``brown_forward`` with (k1, k2, k3, p2, -p1) (y up) for perspective, simple_radial,
  radial and brown; fisheye (focal, k1, k2) and fisheye_opencv (focal_x, focal_y, c_x, c_y,
  k1..k4) are baarda's ``fisheye_forward`` (equidistant); fisheye62, fisheye624, dual,
  spherical and equirectangular are refused (no collinearity model here);
* poses: R_b = R^T diag(1, -1, -1) (baarda's image-to-object rotation, camera looking along
  -z), projection centre X0 = -R^T t;
* ground frame: the topocentric frame is the local east-north-up frame (block/crs.py
  LocalFrame) of the project CRS at reference_lla, so coordinates are used as stored and the
  results are written in the CRS (default: the UTM zone of reference_lla; gcp_list.txt's
  CRS when there is one; `crs` overrides);
* GPS positions with gps_dop > 0 are GNSS observations of the projection centres (sigma
  gps_dop in each axis); GCPs with a position are control points (as check points when
  named in `check_gcp`), those without are tie points.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from baarda.block.camera import INPUT_CALIBRATION
from baarda.block.photo_block import (
    Block,
    Cameras,
    GnssObservations,
    GroundPoints,
    ImagePoints,
    Photos,
    Settings,
)
from baarda.block.pixels import centred
from baarda.errors import ProjectError
from baarda.io.opensfm_camera import Shots, camera_docs, read_shots, stored_errors
from baarda.io.opensfm_files import (
    RECONSTRUCTIONS,
    TRACKS,
    _line,
    _load_json,
    _mapping,
    _vector,
    read_tracks,
)
from baarda.io.opensfm_ground import Control, Ground, control_points, datum_of, ground_frame
from baarda.io.records import check_pixel_options


# ------------------------------------------------------------------ recognising
def _first(folder: Path, names: tuple[str, ...]) -> Path | None:
    for n in names:
        if (folder / n).is_file():
            return folder / n
    return None


def dataset_folder(path: str | Path) -> Path | None:
    """The OpenSfM dataset folder of `path` (itself, or an ODM project's opensfm/)."""
    p = Path(path)
    if not p.is_dir():
        return None
    for cand in (p, p / "opensfm"):
        if cand.is_dir() and _first(cand, RECONSTRUCTIONS) and _first(cand, TRACKS):
            return cand
    return None


def is_opensfm(path: str | Path) -> bool:
    """A folder with an OpenSfM reconstruction and tracks, or an ODM project around one."""
    return dataset_folder(path) is not None


# ------------------------------------------------------------------ the reader
def read_opensfm(path: str | Path, *, pixel_mm: float = 0.001, sigma_px: float = 1.0,
                 crs: str | None = None) -> Block:
    """An OpenSfM dataset or ODM project as a Block (module docstring).

    pixel_mm: nominal pixel size (mm); sigma_px: image sigma (px); crs: the project CRS
    (default: gcp_list.txt's, else the UTM zone of reference_lla).  Check points: see
    block/control.with_check_points (`--check-gcp`)."""
    from pyproj.exceptions import CRSError, ProjError

    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            block = _read(path, pixel_mm, sigma_px, crs)
    except (ProjError, CRSError) as e:  # coordinates that no CRS can hold
        raise ProjectError(str(path), f"coordinates cannot be transformed: {e}") from None
    src = block.source
    for what, values in (("image coordinates (x, y) of tracks or GCPs", block.image.xy_mm),
                         ("shot positions and rotations", block.photos.eo),
                         ("camera focal lengths and principal points",
                          np.column_stack([block.cameras.focal_mm,
                                           block.cameras.principal_point_mm])),
                         ("GPS positions", block.gnss.xyz)):
        if not np.isfinite(values).all():
            raise ProjectError(src, f"{what} out of range (not finite in mm and m)")
    known = block.points.role != "tie"
    given = block.points.xyz[known]
    if not np.all(np.isfinite(given) | np.isnan(block.points.sigma[known])):
        raise ProjectError(src, "GCP coordinates out of range")
    pts = block.points.xyz[~known]
    if np.isinf(pts).any():
        raise ProjectError(src, "point coordinates out of range")
    return block


def _read(path: str | Path, pixel_mm: float, sigma_px: float, crs: str | None) -> Block:
    root = Path(path)
    folder = dataset_folder(root)
    if folder is None:
        raise ProjectError(str(root), "no OpenSfM reconstruction (reconstruction.json) with "
                           "tracks (tracks.csv) here or in opensfm/")
    check_pixel_options(pixel_mm, sigma_px)
    rpath = _first(folder, RECONSTRUCTIONS)
    tpath = _first(folder, TRACKS)
    assert rpath is not None and tpath is not None  # dataset_folder found both
    rec, text, notes = _reconstruction(rpath)
    shots = read_shots(rec, rpath, text, camera_docs(folder, rec, rpath, text), pixel_mm)
    ground = ground_frame(rec, folder, rpath, text, crs, shots)
    tracks = _track_observations(rec, rpath, text, tpath, shots)
    stored = stored_errors(shots.rotation, shots.translation, shots.photo_cam, shots.cameras,
                           tracks.photo, tracks.xyz[tracks.point], tracks.nxy)
    control = control_points(folder, ground, shots, tracks.point_ids)
    pts = _points(shots, tracks, control)
    sig_mm = sigma_px * pixel_mm
    cams = shots.cameras
    cam_ids, photo_ids, ids = (_ids([c.id for c in cams], "camera", notes, rpath),
                               _ids(shots.names, "shot", notes, rpath),
                               _ids(pts.ids, "point", notes, rpath))
    coef = np.zeros((len(cams), 6))
    for k, c in enumerate(cams):
        coef[k, :len(c.coefficients)] = c.coefficients
    cameras = Cameras(cam_ids, np.array([c.focal_mm for c in cams]),
                      np.array([c.pp_mm for c in cams]).reshape(-1, 2),
                      np.array([c.model for c in cams], dtype=object), coef,
                      pixel_frame=centred(len(cams), pixel_mm))
    datum, why = datum_of(pts.xyz, pts.role, pts.rays, shots.gnss_xyz, shots.gnss_sigma)
    settings = Settings(name=root.name, angle_unit="deg", sigma_image_um=sig_mm * 1e3,
                        sigma_control_m=tuple(control.sigma),  # type: ignore[arg-type]  # X, Y, Z
                        crs=ground.crs if ground.frame else None, datum=datum,
                        calibration_free=tuple(c.free for c in cams))
    notes = _notes(notes, folder, tpath, pixel_mm, sigma_px, shots, ground, tracks, control,
                   pts, [why] + ([stored] if stored is not None else []))
    block = Block(settings, cameras,
                  Photos(photo_ids, shots.photo_cam, np.full(len(shots.names), "",
                                                             dtype=object), shots.eo),
                  ImagePoints(pts.photo, pts.point, pts.xy_mm,
                              np.full(len(pts.photo), sig_mm)),
                  GroundPoints(ids, pts.xyz, pts.sigma, pts.role), source=str(root),
                  notes=notes, frame=ground.frame)
    if shots.gnss_rows:
        block = replace(block, gnss=GnssObservations(np.array(shots.gnss_rows, np.int64),
                                                     shots.gnss_xyz, shots.gnss_sigma))
    return block


# ------------------------------------------------------------------ the steps of _read
def _reconstruction(rpath: Path) -> tuple[dict, str, list[str]]:
    """The first reconstruction of the file, its JSON text, and the note on the others."""
    doc, text = _load_json(rpath)
    if isinstance(doc, dict):
        doc = [doc]
    if not isinstance(doc, list) or not doc:
        raise ProjectError(str(rpath), "expected a list of reconstructions", 1)
    rec = _mapping(doc[0], rpath, 1, "reconstruction")
    notes = []
    if len(doc) > 1:
        notes.append(f"{rpath.name}: the first of {len(doc)} reconstructions read (OpenSfM's "
                     "largest); the others are left out")
    return rec, text, notes


@dataclass
class _Tracks:
    """The reconstruction's points and their tracks on its shots (each track once a shot)."""
    point_ids: list[str]
    xyz: np.ndarray
    photo: np.ndarray
    point: np.ndarray
    nxy: np.ndarray  # normalised image coordinates
    outside: int  # rows of shots or points not in the reconstruction
    twice: int  # rows repeating a track on a shot


def _track_observations(rec: dict, rpath: Path, text: str, tpath: Path,
                        shots: Shots) -> _Tracks:
    pts_doc = _mapping(rec.get("points", {}), rpath, _line(text, "points"), "points")
    point_ids = list(pts_doc)
    pindex = {p: j for j, p in enumerate(point_ids)}
    xyz = np.full((len(point_ids), 3), np.nan)
    for j, pid in enumerate(point_ids):
        q = _mapping(pts_doc[pid], rpath, None, "points")
        xyz[j] = _vector(q.get("coordinates"), 3, rpath,
                         partial(_line, text, "points", pid, "coordinates"),
                         "coordinates")
    t_img, t_trk, t_xy, _ = read_tracks(tpath)
    photo = np.array([shots.index.get(im, -1) for im in t_img], dtype=np.int64)
    point = np.array([pindex.get(t, -1) for t in t_trk], dtype=np.int64)
    use = (photo >= 0) & (point >= 0)
    outside = int((~use).sum())
    photo, point, nxy = photo[use], point[use], t_xy[use]
    key = photo * max(1, len(point_ids)) + point
    _, first = np.unique(key, return_index=True)
    once = np.zeros(len(key), bool)
    once[first] = True
    twice = int(len(key) - once.sum())
    return _Tracks(point_ids, xyz, photo[once], point[once], nxy[once], outside, twice)


@dataclass
class _Points:
    """The block's points (the tracks' and the GCPs'), their observations and rays."""
    ids: list[str]
    xyz: np.ndarray
    sigma: np.ndarray
    role: np.ndarray
    photo: np.ndarray
    point: np.ndarray
    xy_mm: np.ndarray
    rays: np.ndarray
    dropped: int  # the reconstruction's points seen by fewer than two shots, left out


def _points(shots: Shots, tracks: _Tracks, control: Control) -> _Points:
    # image coordinates in mm, camera by camera
    photo, point = tracks.photo, tracks.point
    xy_mm = np.zeros((len(photo), 2))
    pc = shots.photo_cam[photo]
    for k, c in enumerate(shots.cameras):
        rows = pc == k
        xy_mm[rows] = c.to_mm(tracks.nxy[rows])
    if control.ids:
        photo = np.concatenate([photo, np.array(control.photo, np.int64)])
        point = np.concatenate([point, np.array(control.point, np.int64)])
        xy_mm = np.vstack([xy_mm, np.array(control.xy_mm).reshape(-1, 2)])
    n = len(tracks.point_ids)
    ids = tracks.point_ids + control.ids
    xyz = np.vstack([tracks.xyz, np.array(control.xyz).reshape(-1, 3)])
    sigma = np.vstack([np.full((n, 3), np.nan), np.array(control.sigmas).reshape(-1, 3)])
    role = np.array(["tie"] * n + control.roles, dtype=object)
    # the reconstruction's points seen by fewer than two shots are left out
    rays = np.bincount(point, minlength=len(ids))
    drop = (rays < 2) & (role == "tie")
    if drop.any():
        keep_pt = ~drop
        new = np.cumsum(keep_pt) - 1
        rows = keep_pt[point]
        photo, point, xy_mm = photo[rows], new[point[rows]], xy_mm[rows]
        ids = [q for q, k in zip(ids, keep_pt, strict=True) if k]
        xyz, sigma, role = xyz[keep_pt], sigma[keep_pt], role[keep_pt]
        rays = rays[keep_pt]  # the rows left out are those of the points left out
    return _Points(ids, xyz, sigma, role, photo, point, xy_mm, rays, int(drop.sum()))


def _notes(notes: list[str], folder: Path, tpath: Path, pixel_mm: float, sigma_px: float,
           shots: Shots, ground: Ground, tracks: _Tracks, control: Control,
           pts: _Points, datum_notes: list[str]) -> list[str]:
    """What was read, converted and left out: the notes so far (on the reconstructions and
    the ids) after the one on the dataset, then the frame, GPS, GCPs, `datum_notes` (the
    datum, the stored reprojection errors) and the rows left out."""
    cams = shots.cameras
    out = [f"OpenSfM dataset {folder}: {len(shots.names)} shots, {len(cams)} "
           f"camera(s) ({', '.join(sorted({c.kind for c in cams}))}), nominal pixel "
           f"size {pixel_mm:g} mm, image sigma {sigma_px:g} px",
           INPUT_CALIBRATION + "the cameras' OpenSfM parameters are estimated "
           f"({'; '.join(', '.join(c.free) for c in cams)})", *notes]
    if ground.frame is not None:
        lla = ground.lla
        assert lla is not None  # the frame is made from it
        out.append(f"topocentric frame of reference_lla (lat {lla[1]:.8f}, lon {lla[0]:.8f}, "
                   f"h {lla[2]:g} m) = the local east-north-up frame of {ground.crs}; "
                   "results in that CRS (heights ellipsoidal)")
    if shots.gnss_rows:
        out.append(f"{len(shots.gnss_rows)} GPS position(s) as GNSS observations of the "
                   "projection centres (sigma gps_dop in each axis)")
    if ground.gcp_file is not None:
        sig = ", ".join(f"{v:g}" for v in control.sigma)
        n_ctrl = int(np.sum(pts.role == "control"))
        out.append(f"{ground.gcp_file.name}: {n_ctrl} control point(s), sigma {sig} m "
                   + ("(config.yaml)" if control.from_config else "(baarda's default; "
                      "config.yaml gcp_horizontal_sd / gcp_vertical_sd set them)"))
    if control.unseen:
        out.append(f"{len(control.unseen)} GCP(s) on no shot of the reconstruction (or without "
                   f"coordinates on one shot) left out: {', '.join(control.unseen[:10])}")
    out += datum_notes
    if tracks.outside or tracks.twice or pts.dropped:
        out.append(f"{tpath.name}: {tracks.outside} row(s) of shots or tracks not in the "
                   f"reconstruction, {tracks.twice} repeated row(s) of a track on a shot and "
                   f"{pts.dropped} point(s) on fewer than two shots left out")
    return out


def _ids(ids: list[str], what: str, notes: list[str], where: Path) -> list[str]:
    """Ids with their commas turned into ';' (the native project's CSV files separate
    fields by commas: OpenSfM's camera ids hold EXIF model names such as 'iphone4,1')."""
    out = [i.replace(",", ";") for i in ids]
    changed = sum(a != b for a, b in zip(ids, out, strict=True))
    if changed:
        if len(set(out)) < len(out):
            raise ProjectError(str(where), f"{what} ids differ only by ',' and ';'")
        first = next(b for a, b in zip(ids, out, strict=True) if a != b)
        notes.append(f"{changed} {what} id(s) with ',' written with ';' (e.g. {first})")
    return out
