"""The ground of an OpenSfM dataset (io/opensfm.py's text gives the conventions): its
topocentric frame placed in the project CRS, the GCPs as control points in it, and the
datum that the control or the GPS positions can carry."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from baarda.errors import ProjectError, figure
from baarda.io.opensfm_files import (
    CONTROL_SIGMA_M,
    GCP_JSON,
    GCP_LIST,
    _config_sigmas,
    _gcp_json,
    _gcp_list,
    _line,
    _load_json,
    _mapping,
    _number,
    utm_crs,
)

if TYPE_CHECKING:
    from baarda.block.crs import LocalFrame
    from baarda.io.opensfm_camera import Shots


@dataclass
class Ground:
    """The ground frame (OpenSfM's topocentric frame in the project CRS) and the GCPs."""
    lla: list[float] | None  # reference_lla: longitude, latitude, altitude
    crs: str | None  # the project CRS
    frame: LocalFrame | None
    gcp_file: Path | None
    gcp_entries: list  # [(id, position or None, [(shot, xy, line)], line)]


def ground_frame(rec: dict, folder: Path, rpath: Path, text: str, crs: str | None,
                 shots: Shots) -> Ground:
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
        gcp_crs, gcp_entries = _gcp_list(gcp_file, shots.camera_of)
    elif gcp_file is not None:
        gcp_entries = _gcp_json(gcp_file, shots.index)
    if ref is not None:
        ref = _mapping(ref, ref_where, _line(text, "reference_lla"), "reference_lla")
        lla = [_number(ref.get(k), ref_where, _line(text, "reference_lla", k), k)
               for k in ("longitude", "latitude", "altitude")]
    else:
        lla = None
    project_crs = crs or gcp_crs or (utm_crs(lla[0], lla[1]) if lla else None)
    # where the CRS comes from, for an error: --crs, gcp_list.txt's first line, or the
    # UTM zone of reference_lla
    crs_where = ("command line", None, None) if crs else \
        (str(gcp_file), _first_line(gcp_file), "crs") if gcp_crs and gcp_file else \
        (str(ref_where), None, None)
    frame = None
    if lla is not None:
        assert project_crs is not None  # the UTM zone of lla at least
        frame = topocentric_frame(project_crs, lla, *crs_where)
    elif gcp_entries or shots.gnss_rows:
        raise ProjectError(str(rpath), "no reference_lla (in the reconstruction or "
                           "reference_lla.json): the GPS positions and GCPs cannot be placed")
    return Ground(lla, project_crs, frame, gcp_file, gcp_entries)


def _first_line(path: Path) -> int:
    """The line of a gcp_list.txt that names the CRS (its first that is not blank or a
    comment)."""
    from baarda.io.text_files import decode_text, file_bytes, split_lines

    for n, s in enumerate(split_lines(decode_text(file_bytes(path), str(path))), start=1):
        if s.strip() and not s.lstrip().startswith("#"):
            return n
    return 1


def topocentric_frame(crs: str, lla: list[float], where: Path | str, line: int | None = None,
                      column: str | None = None):
    """The LocalFrame of `crs` whose local frame is OpenSfM's topocentric frame at lla
    (longitude, latitude, ellipsoidal height, WGS84); a CRS that is not one is an error
    naming `where` (line, column) it came from."""
    from pyproj import CRS, Transformer
    from pyproj.exceptions import CRSError, ProjError

    from baarda.block.crs import LocalFrame

    try:
        target = CRS.from_user_input(crs)
        origin = Transformer.from_crs("EPSG:4979", target.to_3d(), always_xy=True).transform(
            *lla, errcheck=True)  # type: ignore[call-overload]  # pyproj stubs
    except (CRSError, ProjError) as e:
        raise ProjectError(str(where), f"CRS {crs!r}: {e}", line, column) from None
    return LocalFrame(crs, np.array(origin, float))


@dataclass
class Control:
    """The GCPs as points of their own (numbered after the tracks' points)."""
    sigma: tuple[float, float, float]  # of the control points (m)
    from_config: bool  # the sigma is config.yaml's
    ids: list[str] = field(default_factory=list)
    xyz: list = field(default_factory=list)
    sigmas: list = field(default_factory=list)
    roles: list[str] = field(default_factory=list)
    photo: list[int] = field(default_factory=list)
    point: list[int] = field(default_factory=list)
    xy_mm: list = field(default_factory=list)
    unseen: list[str] = field(default_factory=list)  # on no shot (or, without position, on one)


def control_points(folder: Path, ground: Ground, shots: Shots,
                   point_ids: list[str]) -> Control:
    sigma_ctrl = _config_sigmas(folder)
    out = Control(sigma_ctrl or CONTROL_SIGMA_M, sigma_ctrl is not None)
    if not ground.gcp_entries:
        return out
    frame = ground.frame
    taken = set(point_ids)
    lon_lat = None
    assert ground.gcp_file is not None and frame is not None  # control read from it
    if ground.gcp_file.name == GCP_JSON:
        from pyproj import Transformer
        lon_lat = Transformer.from_crs("EPSG:4979", frame.crs3, always_xy=True)
    for pid, where, obs, line in ground.gcp_entries:
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
            _near(c, np.asarray(where), pid, frame, ground.gcp_file, line)
        full = np.isfinite(c)
        rays = len({s for s, _, _ in obs})
        if rays == 0 or (not full.any() and rays < 2):
            out.unseen.append(pid)  # on no shot of the reconstruction; a tie point on one
            continue
        j = len(point_ids) + len(out.ids)
        out.ids.append(name)
        out.xyz.append(c)
        out.sigmas.append(np.where(full, out.sigma, np.nan))
        out.roles.append("control" if full.any() else "tie")
        seen = set()
        for shot, xy, _ in obs:
            if shot in seen:
                continue
            seen.add(shot)
            out.photo.append(shots.index[shot])
            out.point.append(j)
            out.xy_mm.append(shots.camera_of[shot].to_mm(xy)[0])
    return out


MAX_GCP_DISTANCE_M = 100e3  # a GCP farther from the reconstruction's reference is misplaced


def _near(local: np.ndarray, given: np.ndarray, pid: str, frame, path: Path,
          line: int) -> None:
    """ProjectError when a GCP of gcp_list.txt lies farther than MAX_GCP_DISTANCE_M from
    the reconstruction's reference point: its coordinates are not in the CRS that the first
    line names (longitude and latitude under a UTM header were taken as metres, and the
    GCP then fell far outside every photo)."""
    d = float(np.hypot(local[0], local[1]))
    if not d > MAX_GCP_DISTANCE_M:
        return
    hint = ""
    if abs(given[0]) <= 180 and abs(given[1]) <= 90 and not frame.geographic:
        hint = (f"; its X {given[0]:.10g}, Y {given[1]:.10g} look like longitude and latitude:"
                " name EPSG:4326 on the first line, or give the coordinates in "
                f"{frame.crs.name}")
    raise ProjectError(str(path), f"control point {pid} lies {figure(d / 1e3)} km from the "
                       f"reconstruction's reference point (reference_lla): its coordinates are "
                       f"not in {frame.crs.name}, the CRS of the first line" + hint, line, "X")


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
                     f"needed) and {why}; GCPs are check points, GPS positions observations only "
                     "where they fix the datum well (--datum control uses both as control)")
