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

import math
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from baarda.block.photo_block import (
    Block,
    Cameras,
    GnssObservations,
    GroundPoints,
    ImagePoints,
    Photos,
    Settings,
)
from baarda.block.rotation import MAX_ANGLE, eo_of_pose, rodrigues
from baarda.errors import ProjectError
from baarda.io.opensfm_files import (
    CONTROL_SIGMA_M,
    GCP_JSON,
    GCP_LIST,
    RECONSTRUCTIONS,
    TRACKS,
    _Camera,
    _config_sigmas,
    _gcp_json,
    _gcp_list,
    _line,
    _load_json,
    _mapping,
    _number,
    _vector,
    read_tracks,
    utm_crs,
)
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
    pipeline.with_check_points (`--check-gcp`)."""
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
    # cameras: camera_models.json < overrides < the reconstruction's (adjusted) values
    cam_docs: dict[str, tuple[object, Path, str]] = {}
    for name in ("camera_models.json", "camera_models_overrides.json"):
        p = folder / name
        if p.is_file():
            d, t = _load_json(p)
            for cid, c in _mapping(d, p, 1, "cameras").items():
                cam_docs[str(cid)] = (c, p, t)
    for cid, c in _mapping(rec.get("cameras", {}), rpath, _line(text, "cameras"),
                           "cameras").items():
        cam_docs[str(cid)] = (c, rpath, text)
    shots_doc = _mapping(rec.get("shots"), rpath, _line(text, "shots"), "shots") \
        if "shots" in rec else {}
    if not shots_doc:
        raise ProjectError(str(rpath), "the reconstruction has no shots", _line(text, "shots"),
                           "shots")
    names = list(shots_doc)
    cameras: dict[str, _Camera] = {}
    cam_index: dict[str, int] = {}
    eo = np.zeros((len(names), 6))
    rotation = np.zeros((len(names), 3, 3))  # world to camera, as stored
    translation = np.zeros((len(names), 3))
    photo_cam = np.zeros(len(names), np.int64)
    gnss_rows, gnss_xyz, gnss_sig = [], [], []
    for i, sid in enumerate(names):
        line = partial(_line, text, "shots", sid)
        s = _mapping(shots_doc[sid], rpath, line, "shots")
        cid = str(s.get("camera", ""))
        if cid not in cam_docs:
            raise ProjectError(str(rpath), f"shot {sid}: unknown camera {cid!r}", line(),
                               "camera")
        if cid not in cameras:
            c, p, t = cam_docs[cid]
            cameras[cid] = _Camera(cid, c, p, t, pixel_mm)
            cam_index[cid] = len(cam_index)
        photo_cam[i] = cam_index[cid]
        rot = _vector(s.get("rotation"), 3, rpath, partial(line, "rotation"), "rotation")
        tr = _vector(s.get("translation"), 3, rpath,
                     partial(line, "translation"), "translation")
        if not (np.linalg.norm(rot) < MAX_ANGLE):
            raise ProjectError(str(rpath), f"shot {sid}: the rotation {rot.tolist()} is no "
                               "angle-axis vector (|r| is an angle in radians)",
                               line("rotation"), "rotation")
        rotation[i], translation[i] = rodrigues(rot), tr
        eo[i] = eo_of_pose(rotation[i], tr)
        if s.get("gps_position") is not None and s.get("gps_dop") is not None:
            pos = _vector(s["gps_position"], 3, rpath, partial(line, "gps_position"),
                          "gps_position")
            dop = _number(s["gps_dop"], rpath, partial(line, "gps_dop"), "gps_dop")
            if dop > 0:
                gnss_rows.append(i)
                gnss_xyz.append(pos)
                gnss_sig.append((dop, dop, dop))
    shot_index = {n: i for i, n in enumerate(names)}
    cam_list = list(cameras.values())
    cam_of_shot = {n: cam_list[photo_cam[i]] for i, n in enumerate(names)}
    # the ground frame
    ref = rec.get("reference_lla")
    if ref is None and (folder / "reference_lla.json").is_file():
        ref, _ = _load_json(folder / "reference_lla.json")
        ref_where = folder / "reference_lla.json"
    else:
        ref_where = rpath
    gcp_crs, gcp_entries = None, []
    gcp_file = None
    for cand in (folder / GCP_JSON, folder / GCP_LIST, folder.parent / GCP_LIST
                 if folder.name == "opensfm" else None):
        if cand is not None and cand.is_file():
            gcp_file = cand
            break
    if gcp_file is not None and gcp_file.name == GCP_LIST:
        gcp_crs, gcp_entries = _gcp_list(gcp_file, cam_of_shot)
    elif gcp_file is not None:
        gcp_entries = _gcp_json(gcp_file, shot_index)
    if ref is not None:
        ref = _mapping(ref, ref_where, _line(text, "reference_lla"), "reference_lla")
        lla = [_number(ref.get(k), ref_where, _line(text, "reference_lla", k), k)
               for k in ("longitude", "latitude", "altitude")]
    else:
        lla = None
    project_crs = crs or gcp_crs or (utm_crs(lla[0], lla[1]) if lla else None)
    frame = None
    if lla is not None:
        frame = topocentric_frame(project_crs, lla, ref_where)
    elif gcp_entries or gnss_rows:
        raise ProjectError(str(rpath), "no reference_lla (in the reconstruction or "
                           "reference_lla.json): the GPS positions and GCPs cannot be placed")
    # tracks of the reconstruction's points on its shots
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
    photo = np.array([shot_index.get(im, -1) for im in t_img], dtype=np.int64)
    point = np.array([pindex.get(t, -1) for t in t_trk], dtype=np.int64)
    use = (photo >= 0) & (point >= 0)
    outside = int((~use).sum())
    photo, point, nxy = photo[use], point[use], t_xy[use]
    key = photo * max(1, len(point_ids)) + point
    _, first = np.unique(key, return_index=True)
    once = np.zeros(len(key), bool)
    once[first] = True
    twice = int(len(key) - once.sum())
    photo, point, nxy = photo[once], point[once], nxy[once]
    stored = _stored_errors(rotation, translation, photo_cam, cam_list, photo, xyz[point], nxy)
    # control: points of their own, after the tracks' points
    sigma_ctrl = _config_sigmas(folder)
    ctrl_sigma = sigma_ctrl or CONTROL_SIGMA_M
    taken = set(point_ids)
    g_ids, g_xyz, g_sig, g_role = [], [], [], []
    g_photo, g_point, g_xy = [], [], []
    unseen: list[str] = []
    if gcp_entries:
        lon_lat = None
        if gcp_file.name == GCP_JSON:
            from pyproj import Transformer
            lon_lat = Transformer.from_crs("EPSG:4979", frame.crs3, always_xy=True)
        for pid, where, obs, _ in gcp_entries:
            name = pid if pid not in taken else f"gcp {pid}"
            taken.add(name)
            if where is None:
                c = np.full(3, np.nan)
            elif lon_lat is not None:
                lon, lat, alt = where
                c = np.array(lon_lat.transform(lon, lat, 0.0 if math.isnan(alt) else alt,
                                               errcheck=True), float)
                c = frame.to_local(c[None])[0]
                if math.isnan(alt):
                    c[2] = np.nan
            else:
                c = frame.to_local(np.asarray(where)[None])[0]
            full = np.isfinite(c)
            rays = len({s for s, _, _ in obs})
            if rays == 0 or (not full.any() and rays < 2):
                unseen.append(pid)  # on no shot of the reconstruction; a tie point on one
                continue
            j = len(point_ids) + len(g_ids)
            g_ids.append(name)
            g_xyz.append(c)
            g_sig.append(np.where(full, ctrl_sigma, np.nan))
            g_role.append("control" if full.any() else "tie")
            seen = set()
            for shot, xy, _ in obs:
                if shot in seen:
                    continue
                seen.add(shot)
                g_photo.append(shot_index[shot])
                g_point.append(j)
                g_xy.append(cam_of_shot[shot].to_mm(xy)[0])
    # image coordinates in mm, camera by camera
    xy_mm = np.zeros((len(photo), 2))
    pc = photo_cam[photo]
    for k, c in enumerate(cam_list):
        rows = pc == k
        xy_mm[rows] = c.to_mm(nxy[rows])
    if g_ids:
        photo = np.concatenate([photo, np.array(g_photo, np.int64)])
        point = np.concatenate([point, np.array(g_point, np.int64)])
        xy_mm = np.vstack([xy_mm, np.array(g_xy).reshape(-1, 2)])
    ids = point_ids + g_ids
    all_xyz = np.vstack([xyz, np.array(g_xyz).reshape(-1, 3)])
    sigma = np.vstack([np.full((len(point_ids), 3), np.nan), np.array(g_sig).reshape(-1, 3)])
    role = np.array(["tie"] * len(point_ids) + g_role, dtype=object)
    # the reconstruction's points seen by fewer than two shots are left out
    rays = np.bincount(point, minlength=len(ids))
    drop = (rays < 2) & (role == "tie")
    if drop.any():
        keep_pt = ~drop
        new = np.cumsum(keep_pt) - 1
        rows = keep_pt[point]
        photo, point, xy_mm = photo[rows], new[point[rows]], xy_mm[rows]
        ids = [q for q, k in zip(ids, keep_pt, strict=True) if k]
        all_xyz, sigma, role = all_xyz[keep_pt], sigma[keep_pt], role[keep_pt]
        rays = rays[keep_pt]  # the rows left out are those of the points left out
    sig_mm = sigma_px * pixel_mm
    cam_ids, photo_ids, ids = (_ids([c.id for c in cam_list], "camera", notes, rpath),
                               _ids(names, "shot", notes, rpath), _ids(ids, "point", notes,
                                                                       rpath))
    coef = np.zeros((len(cam_list), 6))
    for k, c in enumerate(cam_list):
        coef[k, :len(c.coefficients)] = c.coefficients
    cam = Cameras(cam_ids, np.array([c.focal_mm for c in cam_list]),
                  np.array([c.pp_mm for c in cam_list]).reshape(-1, 2),
                  np.array([c.model for c in cam_list], dtype=object), coef,
                  free=tuple(c.free for c in cam_list))
    n_ctrl = int(np.sum(role == "control"))
    gnss_xyz, gnss_sig = np.array(gnss_xyz), np.array(gnss_sig)
    datum, why = datum_of(all_xyz, role, rays, gnss_xyz, gnss_sig)
    settings = Settings(name=root.name, angle_unit="deg", sigma_image_um=sig_mm * 1e3,
                        sigma_control_m=tuple(ctrl_sigma), crs=project_crs if frame else None,
                        datum=datum)
    notes.insert(0, f"OpenSfM dataset {folder}: {len(names)} shots, {len(cam_list)} "
                 f"camera(s) ({', '.join(sorted({c.kind for c in cam_list}))}), nominal pixel "
                 f"size {pixel_mm:g} mm, image sigma {sigma_px:g} px; the cameras' OpenSfM "
                 f"parameters are estimated ({'; '.join(', '.join(c.free) for c in cam_list)})")
    if frame is not None:
        notes.append(f"topocentric frame of reference_lla (lat {lla[1]:.8f}, lon {lla[0]:.8f}, "
                     f"h {lla[2]:g} m) = the local east-north-up frame of {project_crs}; "
                     "results in that CRS (heights ellipsoidal)")
    if gnss_rows:
        notes.append(f"{len(gnss_rows)} GPS position(s) as GNSS observations of the projection "
                     "centres (sigma gps_dop in each axis)")
    if gcp_file is not None:
        sig = ", ".join(f"{v:g}" for v in ctrl_sigma)
        notes.append(f"{gcp_file.name}: {n_ctrl} control point(s), sigma {sig} m "
                     + ("(config.yaml)" if sigma_ctrl else "(baarda's default; config.yaml "
                        "gcp_horizontal_sd / gcp_vertical_sd set them)"))
    if unseen:
        notes.append(f"{len(unseen)} GCP(s) on no shot of the reconstruction (or without "
                     f"coordinates on one shot) left out: {', '.join(unseen[:10])}")
    notes.append(why)
    if stored is not None:
        notes.append(stored)
    if outside or twice or drop.any():
        notes.append(f"{tpath.name}: {outside} row(s) of shots or tracks not in the "
                     f"reconstruction, {twice} repeated row(s) of a track on a shot and "
                     f"{int(drop.sum())} point(s) on fewer than two shots left out")
    block = Block(settings, cam,
                  Photos(photo_ids, photo_cam, np.full(len(names), "", dtype=object), eo),
                  ImagePoints(photo, point, xy_mm, np.full(len(photo), sig_mm)),
                  GroundPoints(ids, all_xyz, sigma, role), source=str(root), notes=notes,
                  frame=frame)
    if gnss_rows:
        block = replace(block, gnss=GnssObservations(np.array(gnss_rows, np.int64), gnss_xyz,
                                                     gnss_sig))
    return block


def _stored_errors(rotation: np.ndarray, translation: np.ndarray, photo_cam: np.ndarray,
                   cams: list, photo: np.ndarray, xyz: np.ndarray,
                   nxy: np.ndarray) -> str | None:
    """The reprojection errors OpenSfM left: its own projection of the stored points
    against the tracks, in pixels (a note printed before the adjustment); rotation (n, 3, 3)
    and translation (n, 3): the shots' world-to-camera poses."""
    if not len(photo):
        return None
    xc = np.einsum("mij,mj->mi", rotation[photo], xyz) + translation[photo]
    pred = np.zeros_like(nxy)
    size = np.zeros(len(photo))
    for k, c in enumerate(cams):
        rows = photo_cam[photo] == k
        pred[rows] = c.project(xc[rows])
        size[rows] = c.size
    e = (pred - nxy) * size[:, None]
    ok = np.isfinite(e).all(axis=1)
    if not ok.any():
        return None
    e = e[ok]
    n = np.hypot(e[:, 0], e[:, 1])
    return (f"reprojection errors of the stored reconstruction (OpenSfM's projection of its "
            f"points against the tracks, {int(ok.sum())} observations): RMS x "
            f"{np.sqrt(np.mean(e[:, 0]**2)):.3f} px, y {np.sqrt(np.mean(e[:, 1]**2)):.3f} px, "
            f"per coordinate {np.sqrt(np.mean(e**2)):.3f} px, largest {n.max():.1f} px")


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


def datum_of(xyz: np.ndarray, role: np.ndarray, rays: np.ndarray, gnss_xyz: np.ndarray,
             gnss_sigma: np.ndarray) -> tuple[str, str]:
    """("control" or "inner", why): the control datum when the GCPs or the GPS positions can
    carry it, else OpenSfM's own datum (inner constraints on the stored reconstruction, which
    OpenSfM has aligned to its GPS and GCPs) with the GCPs as check points.

    GCPs carry a datum when at least 3 with all coordinates are measured on two or more
    shots (OpenSfM's own rule for using a GCP in its alignment; three so that they can be
    checked against each other); GPS positions when they span a plane: the smaller of their
    two principal horizontal spreads is more than 3 times their sigma (positions along a
    line leave the roll about it free)."""
    good = (role == "control") & np.isfinite(xyz).all(axis=1) & (rays >= 2)
    if good.sum() >= 3:
        return "control", f"datum: the control ({int(good.sum())} GCPs on two or more shots)"
    if len(gnss_xyz) >= 3:
        c = gnss_xyz - gnss_xyz.mean(axis=0)
        spread = np.linalg.svd(c, compute_uv=False) / np.sqrt(len(c))
        sigma = float(np.median(gnss_sigma))
        if spread[1] > 3 * sigma:
            return "control", (f"datum: the GPS positions (planar spread {spread[1]:.3g} m > "
                               f"3 x gps_dop {sigma:g} m)" + (
                                   f" and {int((role == 'control').sum())} GCP(s)"
                                   if (role == "control").any() else ""))
        why = (f"the GPS positions lie close to a line (planar spread {spread[1]:.3g} m, "
               f"gps_dop {sigma:g} m)")
    else:
        why = f"{len(gnss_xyz)} GPS position(s)"
    return "inner", (f"datum: OpenSfM's own (inner constraints on the stored reconstruction): "
                     f"{int(good.sum())} GCP(s) with coordinates on two or more shots (3 "
                     f"needed) and {why}; GCPs are check points, GPS positions are compared "
                     "with the reconstruction's georeference (--datum control uses them as "
                     "control)")


def topocentric_frame(crs: str, lla: list[float], where: Path):
    """The LocalFrame of `crs` whose local frame is OpenSfM's topocentric frame at lla
    (longitude, latitude, ellipsoidal height, WGS84)."""
    from pyproj import CRS, Transformer
    from pyproj.exceptions import CRSError, ProjError

    from baarda.block.crs import LocalFrame

    try:
        target = CRS.from_user_input(crs)
        origin = Transformer.from_crs("EPSG:4979", target.to_3d(), always_xy=True).transform(
            *lla, errcheck=True)
    except (CRSError, ProjError) as e:
        raise ProjectError(str(where), f"CRS {crs!r}: {e}") from None
    return LocalFrame(crs, np.array(origin, float))
