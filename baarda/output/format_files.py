"""Writing the projects of other programs: COLMAP models, BAL files, AICON projects.

The inverses of the readers in baarda.io (round trips are exact); every file is written
atomically.
"""

from __future__ import annotations

import bz2
import struct
from pathlib import Path

import numpy as np

from baarda.io.aicon import AiconProject, _f, _id
from baarda.io.bal import BalProblem
from baarda.io.colmap import MODEL_ID, ColmapModel
from baarda.io.colmap_binary import IMAGE_HEADER, KEYPOINT, POINT_HEADER, TRACK_ELEMENT
from baarda.output.atomic import write_bytes, write_text


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
        rows += [f"{int(c['id'][k]):8d} {int(c['internal'][k]):8d} {_f(c['ck'][k])} "
                 f"{_f(c['xh'][k])} {_f(c['yh'][k])} {_f(c['A1'][k])} {_f(c['A2'][k])} "
                 f"{_f(c['R0'][k])}",
                 f"    {_f(c['A3'][k])}", f"    {_f(c['B1'][k])} {_f(c['B2'][k])}",
                 f"    {_f(c['C1'][k])} {_f(c['C2'][k])}",
                 f"    {_f(c['width_mm'][k])} {_f(c['height_mm'][k])} {int(c['nx'][k])} "
                 f"{int(c['ny'][k])}"]
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
    rows = [f"{_id(p['id'][k]):>10} " + " ".join(repr(float(v)) for v in x[k]) + " " +
            " ".join(repr(float(p[s][k])) for s in ("sX", "sY", "sZ")) +
            f" {int(p['rays'][k])} {int(p['status'][k])} {int(p['new'][k])} {int(p['datum'][k])}"
            for k in range(len(p["id"]))]
    write_text(folder / f"{name}.obc", "\n".join(rows) + "\n")
    o = project.observations
    rows = [f"{int(o['image'][k]):8d} {_id(o['point'][k]):>8} " +
            " ".join(repr(float(o[s][k])) for s in ("x", "y", "sx", "sy", "vx", "vy")) +
            f" {int(o['method'][k])} {int(o['status'][k])} {int(o['internal'][k])}"
            for k in range(len(o["image"]))]
    write_text(folder / f"{name}.phc", "\n".join(rows) + "\n")
    s = project.scale_bars
    rows = [f"{int(s['id'][k])} \"{s['name'][k]}\" {_id(s['a'][k])} {_id(s['b'][k])} "
            f"{_f(s['length'][k])} {_f(s['sigma'][k])} {int(s['status'][k])}"
            for k in range(len(s["id"]))]
    write_text(folder / f"{name}.scale", "\n".join(rows) + ("\n" if rows else ""))
