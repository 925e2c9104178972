"""Writing the projects of other programs: COLMAP models, BAL files, AICON projects,
OpenSfM datasets.

The inverses of the readers in baarda.io (round trips are exact); every file is written
atomically.
"""

from __future__ import annotations

import bz2
import json
import struct
from pathlib import Path

import numpy as np

from baarda.io.aicon import AiconProject, point_id
from baarda.io.bal import BalProblem
from baarda.io.colmap import MODEL_ID, ColmapModel
from baarda.io.colmap_binary import IMAGE_HEADER, KEYPOINT, POINT_HEADER, TRACK_ELEMENT
from baarda.io.opensfm_files import utm_crs
from baarda.io.opensfm_ground import topocentric_frame
from baarda.output.atomic import write_bytes, write_text


def _number(v) -> str:
    """A number of an AICON file: every digit (repr)."""
    return repr(float(v))


def _fmt(v: float) -> str:
    return repr(float(v))


def _lines(tokens: list[str], offsets: np.ndarray) -> list[str]:
    """Lines of the tokens[offsets[k]:offsets[k + 1]], blank-separated."""
    bounds = offsets.tolist()
    return [" ".join(tokens[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def _interleaved(*columns: list[str]) -> list[str]:
    """The tokens of `columns` row by row: a0 b0 a1 b1 ..."""
    out: list[str] = [""] * (len(columns) * len(columns[0]))
    for k, c in enumerate(columns):
        out[k::len(columns)] = c
    return out


def _write_txt(model: ColmapModel, folder: Path) -> None:
    rows = ["# Camera list with one line of data per camera:",
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
            f"# Number of cameras: {len(model.cameras)}"]
    for cid, c in model.cameras.items():
        rows.append(" ".join([str(cid), c.model, str(c.width), str(c.height)] +
                             [_fmt(v) for v in c.params]))
    write_text(folder / "cameras.txt", "\n".join(rows) + "\n")
    im = model.images
    rows = ["# Image list with two lines of data per image:",
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
            "#   POINTS2D[] as (X, Y, POINT3D_ID)", f"# Number of images: {len(im)}"]
    head = _interleaved(*[list(map(str, im.ids.tolist()))] +
                        [list(map(repr, c.tolist())) for c in (*im.qvec.T, *im.tvec.T)] +
                        [list(map(str, im.camera_id.tolist())), list(im.names)])
    heads = _lines(head, 10 * np.arange(len(im) + 1))
    kp = _lines(_interleaved(list(map(repr, im.xys[:, 0].tolist())),
                             list(map(repr, im.xys[:, 1].tolist())),
                             list(map(str, im.point3D_ids.tolist()))), 3 * im.offsets)
    rows += _interleaved(heads, kp)
    write_text(folder / "images.txt", "\n".join(rows) + "\n")
    pt = model.points
    rows = ["# 3D point list with one line of data per point:",
            "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
            f"# Number of points: {len(pt)}"]
    head = _interleaved(*[list(map(str, pt.ids.tolist()))] +
                        [list(map(repr, c.tolist())) for c in pt.xyz.T] +
                        [list(map(str, c.tolist())) for c in pt.rgb.T] +
                        [list(map(repr, pt.error.tolist()))])
    track = _interleaved(list(map(str, pt.image_ids.tolist())),
                         list(map(str, pt.point2D_idxs.tolist())))
    heads = _lines(head, 8 * np.arange(len(pt) + 1))
    tracks = _lines(track, 2 * pt.offsets)
    rows += [f"{h} {t}" if t else h for h, t in zip(heads, tracks, strict=True)]
    write_text(folder / "points3D.txt", "\n".join(rows) + "\n")


def _check_range(values: np.ndarray, dtype: str, what: str) -> np.ndarray:
    info = np.iinfo(dtype)
    if len(values) and (values.min() < info.min or values.max() > info.max):
        raise ValueError(f"{what} outside the range of COLMAP's binary format ({dtype})")
    return values


def _write_bin(model: ColmapModel, folder: Path) -> None:
    from baarda.io import colmap_kernels as ck

    out = [struct.pack("<Q", len(model.cameras))]
    for cid, c in model.cameras.items():
        mid, npar = MODEL_ID[c.model]
        out.append(struct.pack("<iiQQ", cid, mid, c.width, c.height))
        out.append(np.asarray(c.params, "<f8").tobytes())
    write_bytes(folder / "cameras.bin", b"".join(out))
    im = model.images
    n = len(im)
    head = np.empty(n, IMAGE_HEADER)
    head["id"] = _check_range(im.ids, "u4", "image id")
    head["qvec"], head["tvec"] = im.qvec, im.tvec
    head["camera_id"] = _check_range(im.camera_id, "u4", "camera id")
    hb = head.tobytes()
    cb = np.ascontiguousarray(im.keypoint_counts, "<u8").tobytes()
    names = [s.encode("utf-8") + b"\0" for s in im.names]
    # record k: header, name, keypoint count (a), then its keypoints (b)
    a = b"".join(b"".join((hb[64 * k:64 * k + 64], names[k], cb[8 * k:8 * k + 8]))
                 for k in range(n))
    a_off = np.zeros(n + 1, np.int64)
    np.cumsum(IMAGE_HEADER.itemsize + 8 + np.array([len(s) for s in names], np.int64),
              out=a_off[1:])
    kp = np.empty(len(im.point3D_ids), KEYPOINT)
    kp["x"], kp["y"], kp["id"] = im.xys[:, 0], im.xys[:, 1], im.point3D_ids
    body = ck.interleave(np.frombuffer(a, np.uint8), a_off, kp.view(np.uint8),
                         KEYPOINT.itemsize * im.offsets)
    write_bytes(folder / "images.bin", struct.pack("<Q", n) + body.tobytes())
    pt = model.points
    head = np.empty(len(pt), POINT_HEADER)
    head["id"] = pt.ids.view("<u8")  # as read: the bits of COLMAP's uint64 ids
    head["xyz"], head["rgb"], head["error"] = pt.xyz, pt.rgb, pt.error
    head["track_length"] = pt.track_lengths
    track = np.empty(len(pt.image_ids), TRACK_ELEMENT)
    track["image_id"] = _check_range(pt.image_ids, "u4", "track image id")
    track["point2D_idx"] = _check_range(pt.point2D_idxs, "u4", "track keypoint index")
    body = ck.interleave(head.view(np.uint8), POINT_HEADER.itemsize * np.arange(len(pt) + 1),
                         track.view(np.uint8), TRACK_ELEMENT.itemsize * pt.offsets)
    write_bytes(folder / "points3D.bin", struct.pack("<Q", len(pt)) + body.tobytes())


def write_colmap(model: ColmapModel, folder: str | Path, binary: bool = False) -> None:
    """Write the model as text or binary files into `folder` (each file atomically)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (_write_bin if binary else _write_txt)(model, folder)


def write_bal(problem: BalProblem, path: str | Path) -> None:
    """Write a BAL file (bzip2-compressed when the name ends in .bz2), atomically."""
    path = Path(path)
    rows = [f"{len(problem.cameras)} {len(problem.points)} {len(problem.obs_xy)}"]
    rows += [f"{c} {p} {x!r} {y!r}" for c, p, x, y in zip(
        problem.obs_camera.tolist(), problem.obs_point.tolist(), problem.obs_xy[:, 0].tolist(),
        problem.obs_xy[:, 1].tolist(), strict=True)]
    rows += [repr(v) for v in problem.cameras.ravel().tolist()]
    rows += [repr(v) for v in problem.points.ravel().tolist()]
    data = ("\n".join(rows) + "\n").encode("ascii")
    write_bytes(path, bz2.compress(data) if path.suffix == ".bz2" else data)


def write_aicon(project: AiconProject, folder: str | Path, name: str | None = None,
                eo: np.ndarray | None = None, xyz: np.ndarray | None = None) -> None:
    """Write the project's five files; optionally with new EO (image order of the .eor,
    object mm, rad) and point coordinates (order of the .obc, mm)."""
    folder = Path(folder)
    name = name or project.name
    c = project.cameras
    rows = []
    for k in range(len(c["id"])):
        n = {f: _number(c[f][k]) for f in ("ck", "xh", "yh", "A1", "A2", "R0", "A3", "B1",
                                            "B2", "C1", "C2", "width_mm", "height_mm")}
        rows += [f"{int(c['id'][k]):8d} {int(c['internal'][k]):8d} {n['ck']} {n['xh']} "
                 f"{n['yh']} {n['A1']} {n['A2']} {n['R0']}", f"    {n['A3']}",
                 f"    {n['B1']} {n['B2']}", f"    {n['C1']} {n['C2']}",
                 f"    {n['width_mm']} {n['height_mm']} {int(c['nx'][k])} {int(c['ny'][k])}"]
    write_text(folder / f"{name}.ior", "\n".join(rows) + "\n")
    im = project.images
    e = (np.column_stack([im[k] for k in ("X0", "Y0", "Z0", "omega", "phi", "kappa")])
         if eo is None else eo)
    rows = [f"{int(im['id'][k]):8d} {int(im['camera'][k]):6d} " +
            " ".join(repr(float(v)) for v in e[k]) +
            f" {int(im['order'][k])} {int(im['status'][k])} {int(im['orient'][k])}"
            for k in range(len(im["id"]))]
    write_text(folder / f"{name}.eor", "\n".join(rows) + "\n")
    p = project.points
    x = np.column_stack([p[k] for k in "XYZ"]) if xyz is None else xyz
    rows = [f"{point_id(p['id'][k]):>10} " + " ".join(repr(float(v)) for v in x[k]) + " " +
            " ".join(repr(float(p[s][k])) for s in ("sX", "sY", "sZ")) +
            f" {int(p['rays'][k])} {int(p['status'][k])} {int(p['new'][k])} {int(p['datum'][k])}"
            for k in range(len(p["id"]))]
    write_text(folder / f"{name}.obc", "\n".join(rows) + "\n")
    o = project.observations
    rows = [f"{int(o['image'][k]):8d} {point_id(o['point'][k]):>8} " +
            " ".join(repr(float(o[s][k])) for s in ("x", "y", "sx", "sy", "vx", "vy")) +
            f" {int(o['method'][k])} {int(o['status'][k])} {int(o['internal'][k])}"
            for k in range(len(o["image"]))]
    write_text(folder / f"{name}.phc", "\n".join(rows) + "\n")
    s = project.scale_bars
    rows = [f"{int(s['id'][k])} \"{s['name'][k]}\" {point_id(s['a'][k])} {point_id(s['b'][k])} "
            f"{_number(s['length'][k])} {_number(s['sigma'][k])} {int(s['status'][k])}"
            for k in range(len(s["id"]))]
    write_text(folder / f"{name}.scale", "\n".join(rows) + ("\n" if rows else ""))


def write_opensfm(block, folder: str | Path, *, pixel_mm: float = 0.001,
                  reference_lla: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
    """Write a block as an OpenSfM dataset (the inverse of io/opensfm.read_opensfm):
    reconstruction.json, tracks.csv, ground_control_points.json (control and check points:
    read them back with the check points named in --check-gcp), config.yaml (the control
    sigmas).  Ground coordinates are taken as the topocentric frame at reference_lla
    (latitude, longitude, altitude) for a block without a CRS, else the block must be in a
    local frame of its CRS, whose origin is the reference.  Every tie point needs
    coordinates (pipeline.with_tie_coordinates gives both).  Cameras must have the models
    none, brown_forward or fisheye_forward; IMU attitudes and distances have no place in
    OpenSfM (ValueError), nor do height-only control points or GNSS sigmas that differ by
    axis."""
    from pyproj import Transformer

    from baarda.block.camera import coefficients, kinds
    from baarda.block.rotation import pose_of_eo, rotation_vector

    folder = Path(folder)
    if len(block.imu) or len(block.distances):
        raise ValueError("OpenSfM datasets have no IMU attitudes or distances")
    if block.settings.crs and block.frame is None:
        raise ValueError("the block is in its CRS: put it in a local frame first "
                         "(pipeline.with_tie_coordinates)")
    tie = block.points.role == "tie"
    missing = tie & ~np.isfinite(block.points.xyz).all(axis=1)
    if missing.any():
        raise ValueError(f"{int(missing.sum())} tie point(s) without coordinates: intersect "
                         "them first (pipeline.with_tie_coordinates)")
    folder.mkdir(parents=True, exist_ok=True)
    frame = block.frame
    if frame is None:
        lat, lon, h = reference_lla
        frame = topocentric_frame(utm_crs(lon, lat), [lon, lat, h], folder)
    to_lla = Transformer.from_crs(frame.crs3, "EPSG:4979", always_xy=True)
    if block.frame is not None:
        lon, lat, h = to_lla.transform(*frame.from_local(np.zeros((1, 3)))[0])
        reference_lla = (lat, lon, h)
    cams = block.cameras
    kind = kinds(cams)
    im, pts = block.image, block.points
    span = np.abs(im.xy_mm).max(initial=1.0) / pixel_mm
    size = float(2 * int(np.ceil(span)) + 2)  # square frame: max(width, height) = size px
    s = size * pixel_mm  # mm per normalised unit
    cameras = {}
    for i, cid in enumerate(cams.ids):
        if kind[i] not in ("none", "brown_forward", "fisheye_forward"):
            raise ValueError(f"camera {cid}: model {kind[i]} has no OpenSfM equivalent "
                             "(none, brown_forward or fisheye_forward)")
        k = coefficients(cams, i) if kind[i] != "none" else np.zeros(6)
        c, (x0, y0) = float(cams.focal_mm[i]), np.asarray(cams.principal_point_mm[i], float)
        if kind[i] == "fisheye_forward":
            if x0 == 0 and y0 == 0 and not np.any(k[2:]):
                cameras[cid] = {"projection_type": "fisheye", "width": size, "height": size,
                                "focal": c / s, "k1": float(k[0]), "k2": float(k[1])}
            else:
                cameras[cid] = {"projection_type": "fisheye_opencv", "width": size,
                                "height": size, "focal_x": c / s,
                                "focal_y": c / s * (1 + float(k[4])), "c_x": x0 / s,
                                "c_y": -y0 / s, "k1": float(k[0]), "k2": float(k[1]),
                                "k3": float(k[2]), "k4": float(k[3])}
        elif x0 == 0 and y0 == 0 and not np.any(k[2:]):
            cameras[cid] = {"projection_type": "perspective", "width": size, "height": size,
                            "focal": c / s, "k1": float(k[0]), "k2": float(k[1])}
        else:
            cameras[cid] = {"projection_type": "brown", "width": size, "height": size,
                            "focal_x": c / s, "focal_y": c / s * (1 + float(k[5])),
                            "c_x": x0 / s, "c_y": -y0 / s, "k1": float(k[0]),
                            "k2": float(k[1]), "k3": float(k[2]), "p1": -float(k[4]),
                            "p2": float(k[3])}
    shots = {}
    gnss = {int(p): j for j, p in enumerate(block.gnss.photo.tolist())}
    for i, pid in enumerate(block.photos.ids):
        e = block.photos.eo[i]
        if not np.isfinite(e).all():
            raise ValueError(f"photo {pid} has no orientation")
        r, t = pose_of_eo(e)
        shot = {"rotation": rotation_vector(r).tolist(), "translation": t.tolist(),
                "camera": cams.ids[block.photos.camera[i]]}
        if i in gnss:
            sig = block.gnss.sigma[gnss[i]]
            if not np.allclose(sig, sig[0], rtol=1e-12, atol=0):
                raise ValueError(f"photo {pid}: OpenSfM keeps one gps_dop, the GNSS sigmas "
                                 f"differ by axis ({sig.tolist()})")
            shot["gps_position"] = block.gnss.xyz[gnss[i]].tolist()
            shot["gps_dop"] = float(sig[0])
        shots[pid] = shot
    points = {pts.ids[j]: {"coordinates": pts.xyz[j].tolist(), "color": [128, 128, 128]}
              for j in np.flatnonzero(tie)}
    recon = [{"cameras": cameras, "shots": shots, "points": points,
              "reference_lla": {"latitude": reference_lla[0], "longitude": reference_lla[1],
                                "altitude": reference_lla[2]}}]
    write_text(folder / "reconstruction.json", json.dumps(recon, indent=1))
    rows = ["OPENSFM_TRACKS_VERSION_v2"]
    norm = np.column_stack([im.xy_mm[:, 0] / s, -im.xy_mm[:, 1] / s])
    for k in np.flatnonzero(tie[im.point]):
        rows.append(f"{block.photos.ids[im.photo[k]]}\t{pts.ids[im.point[k]]}\t{k}\t"
                    f"{float(norm[k, 0])!r}\t{float(norm[k, 1])!r}\t0.001\t128\t128\t128\t-1\t-1")
    write_text(folder / "tracks.csv", "\n".join(rows) + "\n")
    gcps = []
    ctrl = np.flatnonzero(~tie)
    by_point = np.argsort(im.point, kind="stable")  # the observations grouped by point
    bounds = np.searchsorted(im.point[by_point], np.arange(len(pts.ids) + 1))
    sig = pts.sigma[ctrl[pts.role[ctrl] == "control"]]
    for j in ctrl:
        c = pts.xyz[j]
        if pts.role[j] == "control":  # only the observed coordinates
            c = np.where(np.isfinite(pts.sigma[j]), c, np.nan)
        if not np.isfinite(c[:2]).all():
            raise ValueError(f"point {pts.ids[j]}: OpenSfM GCPs need a horizontal position")
        lo, la, al = to_lla.transform(*frame.from_local(np.where(np.isfinite(c), c,
                                                                 0.0)[None])[0])
        pos = {"latitude": la, "longitude": lo}
        if np.isfinite(c[2]):
            pos["altitude"] = al
        obs = [{"shot_id": block.photos.ids[im.photo[k]], "projection": norm[k].tolist()}
               for k in by_point[bounds[j]:bounds[j + 1]]]
        gcps.append({"id": pts.ids[j], "position": pos, "observations": obs})
    if gcps:
        write_text(folder / "ground_control_points.json", json.dumps({"points": gcps}, indent=1))
    cfg = ["# written by baarda (output/format_files.py write_opensfm)", "bundle_use_gcp: yes"]
    if len(sig):
        h = np.unique(sig[:, :2][np.isfinite(sig[:, :2])])
        v = np.unique(sig[:, 2][np.isfinite(sig[:, 2])])
        if len(h) > 1 or len(v) > 1:
            raise ValueError("OpenSfM keeps one horizontal and one vertical GCP sigma; the "
                             "control points' sigmas differ")
        if len(h):
            cfg.append(f"gcp_horizontal_sd: {float(h[0])!r}")
        if len(v):
            cfg.append(f"gcp_vertical_sd: {float(v[0])!r}")
    write_text(folder / "config.yaml", "\n".join(cfg) + "\n")
