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
from baarda.output.atomic import write_bytes, write_text


def _fmt(v: float) -> str:
    return repr(float(v))


def _write_txt(model: ColmapModel, folder: Path) -> None:
    rows = ["# Camera list with one line of data per camera:",
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
            f"# Number of cameras: {len(model.cameras)}"]
    for cid, c in model.cameras.items():
        rows.append(" ".join([str(cid), c.model, str(c.width), str(c.height)] +
                             [_fmt(v) for v in c.params]))
    write_text(folder / "cameras.txt", "\n".join(rows) + "\n")
    rows = ["# Image list with two lines of data per image:",
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
            "#   POINTS2D[] as (X, Y, POINT3D_ID)", f"# Number of images: {len(model.images)}"]
    for iid, im in model.images.items():
        rows.append(" ".join([str(iid)] + [_fmt(v) for v in im.qvec] +
                             [_fmt(v) for v in im.tvec] + [str(im.camera_id), im.name]))
        rows.append(" ".join(f"{_fmt(x)} {_fmt(y)} {int(i)}"
                             for (x, y), i in zip(im.xys, im.point3D_ids, strict=True)))
    write_text(folder / "images.txt", "\n".join(rows) + "\n")
    rows = ["# 3D point list with one line of data per point:",
            "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
            f"# Number of points: {len(model.points3D)}"]
    for pid, p in model.points3D.items():
        track = np.column_stack([p.image_ids, p.point2D_idxs]).ravel()
        rows.append(" ".join([str(pid)] + [_fmt(v) for v in p.xyz] +
                             [str(int(v)) for v in p.rgb] + [_fmt(p.error)] +
                             [str(int(v)) for v in track]))
    write_text(folder / "points3D.txt", "\n".join(rows) + "\n")


def _write_bin(model: ColmapModel, folder: Path) -> None:
    out = [struct.pack("<Q", len(model.cameras))]
    for cid, c in model.cameras.items():
        mid, npar = MODEL_ID[c.model]
        out.append(struct.pack("<iiQQ", cid, mid, c.width, c.height))
        out.append(np.asarray(c.params, "<f8").tobytes())
    write_bytes(folder / "cameras.bin", b"".join(out))
    out = [struct.pack("<Q", len(model.images))]
    for iid, im in model.images.items():
        out.append(struct.pack("<I7dI", iid, *im.qvec, *im.tvec, im.camera_id))
        out.append(im.name.encode("utf-8") + b"\0")
        out.append(struct.pack("<Q", len(im.xys)))
        rec = np.empty(len(im.xys), [("x", "<f8"), ("y", "<f8"), ("id", "<i8")])
        rec["x"], rec["y"], rec["id"] = im.xys[:, 0], im.xys[:, 1], im.point3D_ids
        out.append(rec.tobytes())
    write_bytes(folder / "images.bin", b"".join(out))
    out = [struct.pack("<Q", len(model.points3D))]
    for pid, p in model.points3D.items():
        out.append(struct.pack("<Q3d3BdQ", pid, *p.xyz, *(int(v) for v in p.rgb), p.error,
                               len(p.image_ids)))
        rec = np.empty(len(p.image_ids), [("im", "<u4"), ("idx", "<u4")])
        rec["im"], rec["idx"] = p.image_ids, p.point2D_idxs
        out.append(rec.tobytes())
    write_bytes(folder / "points3D.bin", b"".join(out))


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
