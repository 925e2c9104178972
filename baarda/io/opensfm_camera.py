"""The cameras and shots of an OpenSfM reconstruction in baarda's terms (io/opensfm.py's
text gives the conventions): projection types, focal length and principal point in mm with
the nominal pixel size, the lens model and its coefficients; the shots' cameras, poses and
GPS positions; and OpenSfM's own projection, by which the reprojection errors of the stored
reconstruction are reported."""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from baarda.block.rotation import MAX_ANGLE, eo_of_pose, rodrigues
from baarda.errors import ProjectError
from baarda.io.opensfm_files import _line, _load_json, _mapping, _number, _vector

SUPPORTED = ("perspective", "simple_radial", "radial", "brown", "fisheye", "fisheye_opencv")
UNSUPPORTED = ("fisheye62", "fisheye624", "dual", "spherical", "equirectangular")


class OpenSfmCamera:
    """One OpenSfM camera in baarda's terms (mm with the nominal pixel size)."""

    def __init__(self, cid: str, d, path: Path, text: str, pixel_mm: float):
        line = _line(text, "cameras", cid)
        d = _mapping(d, path, line, "cameras")
        kind = d.get("projection_type", "perspective")
        kline = _line(text, "cameras", cid, "projection_type") or line
        if kind in UNSUPPORTED:
            raise ProjectError(str(path), f"camera '{cid}': projection type {kind} is not "
                               f"supported (supported: {', '.join(SUPPORTED)})", kline,
                               "projection_type")
        if kind not in SUPPORTED:
            raise ProjectError(str(path), f"camera '{cid}': unknown projection type "
                               f"{kind!r} (supported: {', '.join(SUPPORTED)})", kline,
                               "projection_type")

        def get(key: str, default: float | None = None, positive: bool = False) -> float:
            if key not in d:
                if default is None:
                    raise ProjectError(str(path), f"camera '{cid}': no {key}", line, key)
                return default
            return _number(d[key], path, _line(text, "cameras", cid, key) or line, key,
                           positive=positive)

        self.id, self.kind = cid, kind
        self.width = get("width", positive=True)
        self.height = get("height", positive=True)
        self.size = max(self.width, self.height)
        if kind in ("perspective", "fisheye"):
            fx = fy = get("focal", positive=True)
            cx = cy = 0.0
        else:
            fx = get("focal_x", positive=True)
            fy = get("focal_y", positive=True)
            cx, cy = get("c_x", 0.0), get("c_y", 0.0)
        k1, k2 = get("k1", 0.0), get("k2", 0.0)
        k3 = k4 = p1 = p2 = 0.0
        if kind == "brown":
            k3, p1, p2 = get("k3", 0.0), get("p1", 0.0), get("p2", 0.0)
        if kind == "fisheye_opencv":
            k3, k4 = get("k3", 0.0), get("k4", 0.0)
        self.raw = {"focal_x": fx, "focal_y": fy, "c_x": cx, "c_y": cy, "k1": k1, "k2": k2,
                    "k3": k3, "k4": k4, "p1": p1, "p2": p2}
        s = self.size * pixel_mm
        self.focal_mm = fx * s
        self.pp_mm = (cx * s, -cy * s)
        self.fisheye = kind.startswith("fisheye")
        self.model = "fisheye_forward" if self.fisheye else "brown_forward"
        self.coefficients = (np.array([k1, k2, k3, k4, fy / fx - 1.0]) if self.fisheye else
                             np.array([k1, k2, k3, p2, -p1, fy / fx - 1.0]))
        self.free = {"perspective": ("c", "k1", "k2"), "simple_radial": ("c", "x0", "y0", "k1"),
                     "radial": ("c", "x0", "y0", "k1", "k2"),
                     "brown": ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "a"),
                     "fisheye": ("c", "k1", "k2"),
                     "fisheye_opencv": ("c", "x0", "y0", "k1", "k2", "k3", "k4", "a")}[kind]
        self.scale_mm = s  # mm per normalised unit

    def project(self, xc: np.ndarray) -> np.ndarray:
        """OpenSfM's projection of camera-frame points (m, 3) to normalised coordinates:
        Brown's distortion of (x/z, y/z) (OpenCV's form), then focal and principal point."""
        r = self.raw
        x, y = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
        r2 = x * x + y * y
        if self.fisheye:  # equidistant: theta = atan(r), theta_d = theta (1 + k1 theta^2 ...)
            rr = np.sqrt(r2)
            th = np.arctan(rr)
            t2 = th * th
            thd = th * (1 + t2 * (r["k1"] + t2 * (r["k2"] + t2 * (r["k3"] + t2 * r["k4"]))))
            f = np.where(rr > 0, thd / np.where(rr > 0, rr, 1.0), 1.0)
            return np.column_stack([r["focal_x"] * f * x + r["c_x"],
                                    r["focal_y"] * f * y + r["c_y"]])
        radial = 1 + r2 * (r["k1"] + r2 * (r["k2"] + r2 * r["k3"]))
        xd = x * radial + 2 * r["p1"] * x * y + r["p2"] * (r2 + 2 * x * x)
        yd = y * radial + r["p1"] * (r2 + 2 * y * y) + 2 * r["p2"] * x * y
        return np.column_stack([r["focal_x"] * xd + r["c_x"], r["focal_y"] * yd + r["c_y"]])

    def to_mm(self, xy_n: np.ndarray) -> np.ndarray:
        xy_n = np.asarray(xy_n, float).reshape(-1, 2)
        return np.column_stack([xy_n[:, 0] * self.scale_mm, -xy_n[:, 1] * self.scale_mm])

    def pixels_to_normalised(self, px: np.ndarray) -> np.ndarray:
        px = np.asarray(px, float).reshape(-1, 2)
        return np.column_stack([(px[:, 0] + 0.5 - self.width / 2) / self.size,
                                (px[:, 1] + 0.5 - self.height / 2) / self.size])


def camera_docs(folder: Path, rec: dict, rpath: Path,
                text: str) -> dict[str, tuple[object, Path, str]]:
    """camera id -> (its JSON, file, file text): camera_models.json < overrides < the
    reconstruction's (adjusted) values."""
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
    return cam_docs


@dataclass
class Shots:
    """The reconstruction's shots: their cameras (in the order first used), poses and GPS
    positions."""
    names: list[str]
    index: dict[str, int]  # name -> row
    cameras: list[OpenSfmCamera]
    photo_cam: np.ndarray  # (n,) the camera of each shot
    camera_of: dict[str, OpenSfmCamera]  # name -> its camera
    eo: np.ndarray  # (n, 6) baarda's
    rotation: np.ndarray  # (n, 3, 3) world to camera, as stored
    translation: np.ndarray  # (n, 3)
    gnss_rows: list[int]  # the shots with a GPS position (gps_dop > 0)
    gnss_xyz: np.ndarray
    gnss_sigma: np.ndarray


def read_shots(rec: dict, rpath: Path, text: str, cam_docs: dict, pixel_mm: float) -> Shots:
    shots_doc = _mapping(rec.get("shots"), rpath, _line(text, "shots"), "shots") \
        if "shots" in rec else {}
    if not shots_doc:
        raise ProjectError(str(rpath), "the reconstruction has no shots", _line(text, "shots"),
                           "shots")
    names = list(shots_doc)
    cameras: dict[str, OpenSfmCamera] = {}
    cam_index: dict[str, int] = {}
    eo = np.zeros((len(names), 6))
    rotation = np.zeros((len(names), 3, 3))
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
            cameras[cid] = OpenSfmCamera(cid, c, p, t, pixel_mm)
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
    cam_list = list(cameras.values())
    return Shots(names, {n: i for i, n in enumerate(names)}, cam_list, photo_cam,
                  {n: cam_list[photo_cam[i]] for i, n in enumerate(names)}, eo, rotation,
                  translation, gnss_rows, np.array(gnss_xyz), np.array(gnss_sig))


def stored_errors(rotation: np.ndarray, translation: np.ndarray, photo_cam: np.ndarray,
                  cams: list[OpenSfmCamera], photo: np.ndarray, xyz: np.ndarray,
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
