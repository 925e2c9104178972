"""Writing a Block as a COLMAP model, a BAL file, an OpenSfM dataset or an AICON project, for
`baarda convert --to colmap|bal|opensfm|aicon` (the registry's `writer`): each writer takes
(block, folder) and returns its notes on what the format cannot hold.  The Block is turned
into the format's model object (io/colmap.ColmapModel, io/bal.BalProblem,
io/aicon.AiconProject) and written by
output/format_files.py, the inverses of the readers.

Pixels (block/pixels.pixel_sizes): a camera's pixel is the reader's (`Cameras.pixel_frame`:
width and height), else the size the block states (`Cameras.pixel_mm`), else the nominal
1 µm the readers of pixel formats assume; so a block read from a pixel format goes back in
its own pixels.  Every
point goes out as a tie point (none of these formats has control as baarda means it, but
OpenSfM, whose GCPs keep their given coordinates).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.camera import coefficients, kinds, lens
from baarda.block.photo_block import Block
from baarda.block.pixels import image_sizes, pixel_sizes
from baarda.block.rotation import rotation_matrix, rotation_vector
from baarda.io.aicon import AiconProject, point_id
from baarda.io.bal import BalProblem
from baarda.io.colmap import ColmapCamera, ColmapModel
from baarda.io.colmap_block import eo_to_pose
from baarda.io.colmap_model import ColmapImages, ColmapPoints
from baarda.io.image_sigma import PIXEL_MM
from baarda.output.block_checks import checked_block
from baarda.output.format_files import write_aicon, write_bal, write_colmap, write_opensfm

BAL_FILE = "problem.txt"
GREY = 128


def _pixel_xy(block: Block) -> np.ndarray:
    """(n, 2) the pixel size [mm] in x and y of every camera (block/pixels.pixel_sizes)."""
    return pixel_sizes(block.cameras, PIXEL_MM)


def _lens(block: Block, i: int, fmt: str) -> tuple[str, np.ndarray]:
    """Kind and coefficients of camera i, a model whose coefficients are all 0 as 'none';
    ValueError for a model other than none and brown_forward."""
    kind, coef = lens(block.cameras, i)
    if not np.any(coef):
        return "none", np.zeros(6)
    if kind != "brown_forward":
        raise ValueError(f"camera {block.cameras.ids[i]}: model {kind} has no {fmt} "
                         "equivalent (none or brown_forward: OpenCV's radial and decentring "
                         "on normalised coordinates)")
    return kind, coef


def _keys(block: Block) -> np.ndarray:
    """The observations' order photo by photo (stable): each photo's keypoints."""
    return np.argsort(block.image.photo, kind="stable")


def _integer_ids(ids: list[str]) -> np.ndarray | None:
    """The ids as int64 when all are distinct positive integers (COLMAP ids), else None."""
    if not ids or not all(s.isdigit() and s == str(int(s)) and int(s) > 0 for s in ids):
        return None
    out = np.array([int(s) for s in ids], np.int64)
    return out if len(np.unique(out)) == len(out) and out.max() < 2 ** 31 else None


def block_to_colmap(block: Block) -> tuple[ColmapModel, list[str]]:
    """The COLMAP model of `block` and the notes on what it cannot hold.

    Cameras: none -> SIMPLE_PINHOLE (PINHOLE with non-square pixels), brown_forward -> the
    smallest of SIMPLE_RADIAL (k1), RADIAL (k1, k2), OPENCV (k1, k2 and decentring: COLMAP's
    p1, p2 are baarda's -p2, p1, y pointing down) and FULL_OPENCV (k3); the aspect a as fy =
    fx (1 + a).  Image size: block/pixels.image_sizes (the block's where its grid is
    known, else the smallest even frame around the observations); the principal point
    cx = w/2 + x0/px, cy = h/2 - y0/py, the keypoints x = w/2 + x/px, y = h/2 - y/py
    (pixel corner at the upper-left of the image).
    Image names: the photo ids + '.jpg' (COLMAP's reader takes the stem as photo id); image
    and camera ids 1, 2, ...; point ids kept where they are positive integers."""
    notes = checked_block(block, coordinates=True, roles=True)
    cams, photos, im = block.cameras, block.photos, block.image
    bad = [p for p in photos.ids if not p or any(ch.isspace() for ch in p)]
    if bad:
        raise ValueError(f"photo id '{bad[0]}': COLMAP image names have no blanks")
    pxy = _pixel_xy(block)
    cam_of = photos.camera[im.photo]
    size = image_sizes(cams, cam_of, im.xy_mm, pxy)
    cameras, aspect = {}, []
    for i in range(len(cams)):
        kind, k = _lens(block, i, "COLMAP")
        c, (x0, y0) = float(cams.focal_mm[i]), cams.principal_point_mm[i]
        px, py = pxy[i]
        w, h = (int(v) for v in size[i])
        a = float(k[5])
        if a:
            aspect.append(cams.ids[i])
        fx, fy = c / px, c * (1 + a) / py
        cx, cy = w / 2 + x0 / px, h / 2 - y0 / py
        k1, k2, k3, p1, p2 = (float(v) for v in k[:5])
        square = fx == fy
        if square and not np.any(k[1:5]):
            model, params = (("SIMPLE_RADIAL", [fx, cx, cy, k1]) if k1 else
                             ("SIMPLE_PINHOLE", [fx, cx, cy]))
        elif not square and not np.any(k[:5]):
            model, params = "PINHOLE", [fx, fy, cx, cy]
        elif square and not np.any(k[2:5]):
            model, params = "RADIAL", [fx, cx, cy, k1, k2]
        elif not k3:
            model, params = "OPENCV", [fx, fy, cx, cy, k1, k2, -p2, p1]
        else:
            model, params = "FULL_OPENCV", [fx, fy, cx, cy, k1, k2, -p2, p1, k3, 0, 0, 0]
        cameras[i + 1] = ColmapCamera(model, w, h, np.array(params, float))
    if aspect:
        notes.append(f"camera(s) {', '.join(aspect)}: the aspect a written as fy = fx (1 + a);"
                     " read back it is a y pixel size of px fx/fy (the same pixels)")
    used = np.unique(im.point)
    given = _integer_ids([block.points.ids[j] for j in used])
    point_id = np.zeros(len(block.points.ids), np.int64)
    point_id[used] = given if given is not None else np.arange(1, len(used) + 1)
    order = _keys(block)
    ph, pt = im.photo[order], im.point[order]
    w = np.array([cameras[i + 1].width for i in range(len(cams))], float)[cam_of[order]]
    h = np.array([cameras[i + 1].height for i in range(len(cams))], float)[cam_of[order]]
    xy = np.column_stack([w / 2 + im.xy_mm[order, 0] / pxy[cam_of[order], 0],
                          h / 2 - im.xy_mm[order, 1] / pxy[cam_of[order], 1]])
    n = len(photos)
    counts = np.bincount(ph, minlength=n)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    poses = [eo_to_pose(e) for e in photos.eo]
    images = ColmapImages(np.arange(1, n + 1, dtype=np.int64),
                          np.array([q for q, _ in poses]).reshape(n, 4),
                          np.array([t for _, t in poses]).reshape(n, 3),
                          photos.camera.astype(np.int64) + 1,
                          [f"{p}.jpg" for p in photos.ids], offsets, xy,
                          point_id[pt].astype(np.int64))
    # tracks: (image id, keypoint index) of every observation, point by point
    key = np.arange(len(order)) - offsets[ph]
    by_point = np.argsort(pt, kind="stable")
    bounds = np.searchsorted(pt[by_point], used)
    track_counts = np.diff(np.append(bounds, len(by_point)))
    points = ColmapPoints(point_id[used], block.points.xyz[used].astype(float),
                          np.full((len(used), 3), GREY, np.uint8), np.zeros(len(used)),
                          np.concatenate([[0], np.cumsum(track_counts)]).astype(np.int64),
                          (ph[by_point] + 1).astype(np.int64), key[by_point].astype(np.int64))
    notes.append("COLMAP: image names are the photo ids + .jpg, colours grey, errors 0"
                 + ("" if given is not None else ", point ids renumbered")
                 + "; no image sigmas (give --sigma-px when reading)")
    return ColmapModel(cameras, images, points), notes


def write_colmap_block(block: Block, folder: str | Path) -> list[str]:
    """cameras.txt, images.txt, points3D.txt of `block` in `folder` (block_to_colmap); the
    notes on what was dropped."""
    model, notes = block_to_colmap(block)
    write_colmap(model, folder)
    return notes


def block_to_bal(block: Block) -> tuple[BalProblem, list[str]]:
    """The BAL problem of `block` and the notes: one BAL camera per photo (r, t, f, k1, k2
    with f = c/px in pixels and BAL's radial terms, which are brown_forward's k1, k2), the
    points in block order of the observed ones, the observations in pixels from the
    principal point (x - x0)/px, (y - y0)/py, y up (BAL's camera frame is baarda's:
    R = R_b^T, t = -R X0)."""
    notes = checked_block(block, coordinates=True, roles=True, principal_point=True)
    cams, photos, im = block.cameras, block.photos, block.image
    pxy = _pixel_xy(block)
    n = len(photos)
    table = np.zeros((n, 9))
    rb = rotation_matrix(photos.eo[:, 3], photos.eo[:, 4], photos.eo[:, 5])
    r = np.swapaxes(rb, 1, 2)
    table[:, :3] = rotation_vector(r)
    table[:, 3:6] = -np.einsum("nij,nj->ni", r, photos.eo[:, :3])
    for i in range(len(cams)):
        kind, k = _lens(block, i, "BAL")
        if np.any(k[2:]):
            raise ValueError(f"camera {cams.ids[i]}: {k.tolist()} has no BAL equivalent "
                             "(k1, k2 only)")
        if not np.isclose(pxy[i, 0], pxy[i, 1], rtol=1e-12, atol=0):
            raise ValueError(f"camera {cams.ids[i]}: BAL has square pixels only")
        on = photos.camera == i
        table[on, 6] = float(cams.focal_mm[i]) / pxy[i, 0]
        table[on, 7:9] = k[:2]
    used = np.unique(im.point)
    index = np.full(len(block.points.ids), -1, np.int64)
    index[used] = np.arange(len(used))
    cam = photos.camera[im.photo]
    xy = (im.xy_mm - cams.principal_point_mm[cam]) / pxy[cam]
    notes.append("BAL: one camera per photo (f, k1, k2 in pixels), photos and points numbered "
                 "from 0 (no ids), no principal point, no image sigmas; read back, f, k1, k2 "
                 "are estimated unless --calibrate none")
    return BalProblem(table, block.points.xyz[used].astype(float), im.photo.astype(np.int64),
                      index[im.point], xy), notes


def write_bal_block(block: Block, folder: str | Path) -> list[str]:
    """`folder`/problem.txt of `block` (block_to_bal); the notes on what was dropped."""
    problem, notes = block_to_bal(block)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_bal(problem, folder / BAL_FILE)
    return notes


def write_opensfm_block(block: Block, folder: str | Path) -> list[str]:
    """reconstruction.json, tracks.csv, ground_control_points.json, config.yaml of `block`
    in `folder` (format_files.write_opensfm, in the pixels of the first camera); the notes
    on what was dropped."""
    notes = checked_block(block, coordinates=True)
    px = _pixel_xy(block)
    if not np.allclose(px, px[0, 0], rtol=1e-12, atol=0):
        raise ValueError("OpenSfM normalises every camera by one image size: the cameras' "
                         "pixel sizes differ (or are not square)")
    write_opensfm(block, folder, pixel_mm=float(px[0, 0]))
    checks = int(np.sum(block.points.role == "check"))
    notes.append("OpenSfM: square images around the observations, colours grey, no image "
                 "sigmas (give --sigma-px when reading), tie point ids kept"
                 + (f"; {checks} check point(s) written as GCPs (read them back with "
                    "--check-gcp)" if checks else ""))
    return notes


def _aicon_ids(ids: list[str], what: str, notes: list[str]) -> tuple[np.ndarray, bool]:
    """AICON's numeric ids of `ids` (float), kept where every id reads back as itself
    (aicon.point_id), else 1, 2, ... (noted); and whether they were kept."""
    try:
        values = np.array([float(s) for s in ids])
        kept = all(point_id(v) == s for v, s in zip(values, ids, strict=True)) and \
            len(set(ids)) == len(ids)
    except ValueError:
        kept = False
    if kept:
        return values, True
    notes.append(f"{what} ids renumbered 1, 2, ... (AICON's ids are numbers)")
    return np.arange(1.0, len(ids) + 1), False


def block_to_aicon(block: Block, name: str = "block") -> tuple[AiconProject, list[str]]:
    """The AICON project of `block` and the notes: cameras with AICON's model (ck = -c, xh,
    yh = the principal point, A1..A3 with R0, B1, B2, C1, C2; a camera without terms as all
    zero), orientations and points in mm, the observations with their sigmas sx, sy [mm],
    the distances as scale bars [mm]; every image, point and observation active."""
    notes = checked_block(block, coordinates=True, roles=True)
    cams, photos, im, pts = block.cameras, block.photos, block.image, block.points
    kind = kinds(cams)
    n_c = len(cams)
    coef = np.zeros((n_c, 7))
    r0 = np.zeros(n_c)
    for i in range(n_c):
        k = coefficients(cams, i)
        if kind[i] == "aicon":
            coef[i] = k
            c = cams.constants
            r0[i] = 0.0 if c is None else float(np.asarray(c, float).reshape(n_c, -1)[i, 0])
        elif np.any(k):
            raise ValueError(f"camera {cams.ids[i]}: model {kind[i]} has no AICON "
                             "equivalent (aicon, or a camera without terms)")
    cam_id, _ = _aicon_ids(cams.ids, "camera", notes)
    photo_id, _ = _aicon_ids(photos.ids, "photo", notes)
    used = np.unique(np.concatenate([im.point, block.distances.point_a,
                                     block.distances.point_b]).astype(np.int64))
    pid, _ = _aicon_ids([pts.ids[j] for j in used], "point", notes)
    size = np.abs(im.xy_mm).max(initial=1.0) * 2
    cameras = {"id": cam_id, "internal": np.zeros(n_c), "ck": -np.asarray(cams.focal_mm, float),
               "xh": cams.principal_point_mm[:, 0].astype(float),
               "yh": cams.principal_point_mm[:, 1].astype(float), "R0": r0,
               "width_mm": np.full(n_c, size), "height_mm": np.full(n_c, size),
               "nx": np.zeros(n_c), "ny": np.zeros(n_c)}
    cameras.update({f: coef[:, k] for k, f in enumerate(("A1", "A2", "A3", "B1", "B2", "C1",
                                                         "C2"))})
    n = len(photos)
    eo = photos.eo
    images = {"id": photo_id, "camera": cam_id[photos.camera], "X0": eo[:, 0] * 1e3,
              "Y0": eo[:, 1] * 1e3, "Z0": eo[:, 2] * 1e3, "omega": eo[:, 3], "phi": eo[:, 4],
              "kappa": eo[:, 5], "order": np.zeros(n), "status": np.ones(n),
              "orient": np.zeros(n)}
    m = len(used)
    xyz = pts.xyz[used] * 1e3
    rays = np.bincount(im.point, minlength=len(pts.ids))[used]
    points = {"id": pid, "X": xyz[:, 0], "Y": xyz[:, 1], "Z": xyz[:, 2], "sX": np.zeros(m),
              "sY": np.zeros(m), "sZ": np.zeros(m), "rays": rays, "status": np.ones(m),
              "new": np.zeros(m), "datum": np.zeros(m)}
    index = np.full(len(pts.ids), -1, np.int64)
    index[used] = np.arange(m)
    k = len(im.photo)
    sxy = im.sigma_xy
    observations = {"image": photo_id[im.photo], "point": pid[index[im.point]],
                    "x": im.xy_mm[:, 0], "y": im.xy_mm[:, 1], "sx": sxy[:, 0], "sy": sxy[:, 1],
                    "vx": np.zeros(k), "vy": np.zeros(k), "method": np.zeros(k),
                    "status": np.ones(k), "internal": np.zeros(k)}
    d = block.distances
    bad = [s for s in d.ids if '"' in s]
    if bad:
        raise ValueError(f"distance '{bad[0]}': AICON's scale bar names have no quotes")
    scale = {"id": np.arange(1, len(d) + 1), "name": list(d.ids),
             "a": pid[index[d.point_a]], "b": pid[index[d.point_b]],
             "length": np.asarray(d.length_m, float) * 1e3,
             "sigma": np.asarray(d.sigma_m, float) * 1e3, "status": np.ones(len(d))}
    notes = [n for n in notes if "observations not written" not in n]
    extra = [w for w, v in (("GNSS", block.gnss), ("IMU", block.imu)) if len(v)]
    if extra:
        notes.append(f"{', '.join(extra)} observations not written (no place in the format)")
    notes.append("AICON: object coordinates in mm, no point sigmas, read back as a free "
                 "network in the inner datum estimating AICON's default camera parameters "
                 "(give --calibrate none for the cameras as written)")
    return AiconProject(name, Path("."), cameras, images, points, observations, scale), notes


def write_aicon_block(block: Block, folder: str | Path) -> list[str]:
    """block.ior, .eor, .obc, .phc, .scale of `block` in `folder` (block_to_aicon); the
    notes on what was dropped."""
    project, notes = block_to_aicon(block)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_aicon(project, folder)
    return notes
