"""AICON 3D Studio bundle files: NAME.ior, .eor, .obc, .phc, .scale (whitespace separated).

Columns (from the German comments of the JAiCov readers; '#' lines are comments):

* .ior, five lines per camera: (1) camera no., internal, ck, xh, yh, A1, A2, R0; (2) A3;
  (3) B1, B2; (4) C1, C2; (5) sensor width, height [mm], pixels x, y;
* .eor: image no., camera no., X0, Y0, Z0 [mm], omega, phi, kappa [rad], rotation order
  (0 = AICON "CAP"), image status (0 = inactive), orientation status (1 = not oriented);
* .obc: point id, X, Y, Z [mm], sX, sY, sZ, rays, status (1 = active), new-point flag,
  datum flag;
* .phc: image no., point id, x, y [mm], sx, sy, residuals vx, vy, method code, status
  (> 0 active), internal parameter;
* .scale: id, "name", point A, point B, length [mm], sigma [mm], status.

Conventions, checked by reprojecting AICON's own solution (tests/io/test_aicon.py: 0.04 mm
RMS, the size of AICON's lens distortion, whose radial part the residuals follow with
correlation 0.998): the rotation is baarda's R_x(omega) R_y(phi) R_z(kappa) (image to
object); AICON's negative ck means the image plane at z = ck, baarda's c = -ck; image
coordinates are in mm relative to the image centre (x right, y up), principal point
(xh, yh).  Object coordinates are converted from mm to m.

AICON's distortion model (A1..A3 radial with zero crossing R0, B1, B2 decentring, C1, C2
affinity and shear) is read and kept in `AiconProject`, but not yet applied: the block
gets lens model 'none' and a note says so (the model is a later step).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from baarda.block.camera import INPUT_CALIBRATION
from baarda.block.photo_block import (
    Block,
    Cameras,
    Distances,
    GroundPoints,
    ImagePoints,
    Photos,
    Settings,
)
from baarda.errors import ProjectError
from baarda.io.aicon_protocol import AiconProtocol, read_protocol
from baarda.io.image_sigma import SIGMA_IMAGE_UM
from baarda.io.records import refuse_repeats, to_numbers
from baarda.io.text_files import ENCODING, whole_lines

EXTENSIONS = ("ior", "eor", "obc", "phc", "scale")
# the camera parameters AICON 3D Studio estimates by default (A3, C1, C2 held)
DEFAULT_FREE = ("c", "x0", "y0", "a1", "a2", "b1", "b2")


@dataclass
class AiconProject:
    name: str
    folder: Path
    cameras: dict  # field -> array (n_cam,): id, internal, ck, xh, yh, A1, A2, R0, A3, ...
    images: dict  # id, camera, X0, Y0, Z0, omega, phi, kappa, order, status, orient
    points: dict  # id, X, Y, Z, sX, sY, sZ, rays, status, new, datum
    observations: dict  # image, point, x, y, sx, sy, vx, vy, method, status, internal
    scale_bars: dict  # id, name, a, b, length, sigma, status

    # ------------------------------------------------------------- what is used
    def active_images(self) -> np.ndarray:
        im = self.images
        return (im["status"] != 0) & (im["orient"] != 1) & (im["order"] == 0)

    def active_points(self) -> np.ndarray:
        return self.points["status"] == 1

    def active_observations(self) -> np.ndarray:
        o = self.observations
        img = set(self.images["id"][self.active_images()])
        pts = set(self.points["id"][self.active_points()])
        return ((o["status"] > 0) & np.isin(o["image"], list(img)) &
                np.isin(o["point"], list(pts)))

    def active_scale_bars(self) -> np.ndarray:
        return self.scale_bars["status"] != 0

    def counts(self) -> dict:
        """Observations (image coordinates and scale bars), points and images in use."""
        n_obs = int(self.active_observations().sum())
        n_sb = int(self.active_scale_bars().sum())
        return {"observations": 2 * n_obs + n_sb, "image_points": n_obs, "scale_bars": n_sb,
                "points": int(self.active_points().sum()),
                "images": int(self.active_images().sum())}

    def to_block(self, sigma_image_mm: float | None = None) -> Block:
        """The active images, points and observations as a Block (object units m).

        sigma_image_mm: a-priori sigma of the image coordinates; default: the sx, sy of the
        .phc file (AICON's report used 0.0005 mm for this example, not the file's values).
        """
        cams = self.cameras
        cam_ids = [str(int(c)) for c in cams["id"]]
        protocol = self.protocol()
        free = protocol.free if protocol is not None else DEFAULT_FREE
        coef = np.column_stack([cams[k] for k in ("A1", "A2", "A3", "B1", "B2", "C1", "C2")])
        cameras = Cameras(cam_ids, -cams["ck"], np.column_stack([cams["xh"], cams["yh"]]),
                          np.full(len(cam_ids), "aicon", dtype=object), coef,
                          cams["R0"][:, None].astype(float))
        act_i = self.active_images()
        im = {k: v[act_i] for k, v in self.images.items()}
        cam_index = {int(c): i for i, c in enumerate(cams["id"])}
        missing = [c for c in im["camera"] if int(c) not in cam_index]
        if missing:
            raise ProjectError(str(self.folder / f"{self.name}.eor"),
                               f"image uses unknown camera {int(missing[0])}")
        photo_ids = [str(int(i)) for i in im["id"]]
        eo = np.column_stack([np.column_stack([im["X0"], im["Y0"], im["Z0"]]) * 1e-3,
                              im["omega"], im["phi"], im["kappa"]])
        photos = Photos(photo_ids, np.array([cam_index[int(c)] for c in im["camera"]]),
                        np.full(len(photo_ids), "", dtype=object), eo)
        act_p = self.active_points()
        pid = self.points["id"][act_p]
        xyz = np.column_stack([self.points[k][act_p] for k in "XYZ"]) * 1e-3
        points = GroundPoints([point_id(p) for p in pid], xyz, np.full(xyz.shape, np.nan),
                              np.full(len(pid), "tie", dtype=object))
        o = {k: v[self.active_observations()] for k, v in self.observations.items()}
        if not len(o["x"]):
            raise ProjectError(str(self.folder / f"{self.name}.phc"), "no active observations "
                               "(status > 0, of an image with status != 0 and a point with "
                               "status 1)")
        pi = {int(p): i for i, p in enumerate(im["id"])}
        qi = {p: j for j, p in enumerate(pid.tolist())}
        sxy = np.column_stack([o["sx"], o["sy"]])
        if protocol is not None and len(protocol.observations["sx"]):  # AICON's a-priori
            po = protocol.observations
            key = {(int(i), str(p)): k for k, (i, p) in enumerate(zip(
                po["image"].tolist(), po["point"].tolist(), strict=True))}
            rows = np.array([key.get((int(i), point_id(p)), -1) for i, p in zip(
                o["image"].tolist(), o["point"].tolist(), strict=True)])
            found = rows >= 0
            sxy[found] = np.column_stack([po["sx"], po["sy"]])[rows[found]]
        if sigma_image_mm is not None:
            sig = np.full(len(o["x"]), sigma_image_mm)
        else:
            with np.errstate(over="ignore"):
                sig = np.sqrt(0.5 * (sxy ** 2).sum(axis=1))
            big = ~np.isfinite(sig)  # the squares overflowed
            sig[big] = np.hypot(sxy[big, 0], sxy[big, 1]) / np.sqrt(2.0)
        per_axis = None if sigma_image_mm is not None else sxy
        image = ImagePoints(np.array([pi[int(i)] for i in o["image"]], dtype=np.int64),
                            np.array([qi[p] for p in o["point"].tolist()], dtype=np.int64),
                            np.column_stack([o["x"], o["y"]]), sig, None, per_axis)
        distances = self.distances(points.ids)
        notes = [f"AICON project {self.name}: object coordinates mm -> m; c = -ck; camera "
                 "model 'aicon' (A1..A3 with R0, B1, B2, C1, C2)",
                 f"{len(distances)} scale bar(s) as distance observations (mm -> m)",
                 "datum: AICON's own, a free network in the inner datum of its points (as "
                 "AICON 3D Studio adjusts it; --datum free holds photo 1 instead)"]
        if protocol is not None:
            notes.append(f"AICON protocol {protocol.path.name}: the a-priori sigmas of the "
                         "image coordinates taken from it")
            notes.append(INPUT_CALIBRATION + f"the camera parameters {protocol.path.name} "
                         "estimates are estimated (" + ", ".join(free) + ")")
        else:
            notes.append(INPUT_CALIBRATION + "no AICON protocol (.htm) beside the project: "
                         "the camera parameters AICON estimates by default are estimated ("
                         + ", ".join(free) + ")")
        settings = Settings(name=self.name, angle_unit="rad",
                            sigma_image_um=float(np.median(sig)) * 1e3, datum="inner",
                            calibration_free=(free,) * len(cam_ids))
        return Block(settings, cameras, photos, image, points,
                     source=str(self.folder / self.name), notes=notes, distances=distances)

    def protocol(self) -> AiconProtocol | None:
        """The AICON bundle protocol beside the project (<name>.htm), if there is one."""
        path = self.folder / f"{self.name}.htm"
        return read_protocol(path) if path.is_file() else None

    def distances(self, point_ids: list[str]) -> Distances:
        """The active scale bars between active points, in m."""
        sb = self.scale_bars
        index = {p: i for i, p in enumerate(point_ids)}
        keep = [k for k in np.flatnonzero(self.active_scale_bars())
                if point_id(sb["a"][k]) in index and point_id(sb["b"][k]) in index]
        return Distances([str(sb["name"][k]) for k in keep],
                         np.array([index[point_id(sb["a"][k])] for k in keep], np.int64),
                         np.array([index[point_id(sb["b"][k])] for k in keep], np.int64),
                         np.array([sb["length"][k] for k in keep], float) * 1e-3,
                         np.array([sb["sigma"][k] for k in keep], float) * 1e-3)


def point_id(v) -> str:
    """An AICON point or image id as text: '12' for 12.0, else every digit."""
    v = float(v)
    return str(int(v)) if v.is_integer() else repr(v)


def _stem(path: Path) -> tuple[Path, str]:
    if path.is_dir():
        stems = sorted({p.stem for p in path.glob("*.phc")})
        if len(stems) != 1:
            raise ProjectError(str(path), f"expected one AICON project (*.phc), found "
                               f"{len(stems)}")
        return path, stems[0]
    if path.suffix.lower().lstrip(".") not in EXTENSIONS:
        raise ProjectError(str(path), "not an AICON file (.ior, .eor, .obc, .phc, .scale)")
    return path.parent, path.stem


def is_aicon(path: str | Path) -> bool:
    p = Path(path)
    try:
        folder, stem = _stem(p)
    except ProjectError:
        return False
    return all((folder / f"{stem}.{e}").is_file() for e in ("ior", "eor", "obc", "phc"))


def _table(path: Path, names: list[str], ints: tuple[str, ...] = (),
           encoding: str = ENCODING) -> dict:
    rows, lines = [], []
    for no, s in enumerate(whole_lines(path, encoding), start=1):
        t = s.strip()
        if not t or t.startswith("#"):
            continue
        parts = t.split()
        if len(parts) != len(names):
            raise ProjectError(str(path), f"expected {len(names)} columns ({', '.join(names)}),"
                               f" found {len(parts)}", no)
        rows.append(parts)
        lines.append(no)
    data = np.array(rows, dtype=str).reshape(-1, len(names))
    ln = np.array(lines, dtype=np.int64)
    out = {"_lines": ln}
    for k, n in enumerate(names):
        v = to_numbers(data[:, k], str(path), ln, n)
        if n in ints and np.any(v != np.round(v)):
            bad = int(np.flatnonzero(v != np.round(v))[0])
            raise ProjectError(str(path), f"'{data[bad, k]}' is not an integer", int(ln[bad]), n)
        out[n] = v
    return out


def _read_ior(path: Path, encoding: str = ENCODING) -> dict:
    lines = [(no, s.split()) for no, s in enumerate(whole_lines(path, encoding), start=1)
             if s.strip() and not s.lstrip().startswith("#")]
    if not lines or len(lines) % 5:
        raise ProjectError(str(path), f"expected 5 lines per camera, found {len(lines)} lines",
                           lines[-1][0] if lines else None)
    shape = [("id", "internal", "ck", "xh", "yh", "A1", "A2", "R0"), ("A3",), ("B1", "B2"),
             ("C1", "C2"), ("width_mm", "height_mm", "nx", "ny")]
    out: dict[str, list[float]] = {n: [] for names in shape for n in names}
    for c in range(len(lines) // 5):
        for k, names in enumerate(shape):
            no, parts = lines[5 * c + k]
            if len(parts) != len(names):
                raise ProjectError(str(path), f"line {k + 1} of a camera needs {len(names)} "
                                   f"values ({', '.join(names)}), found {len(parts)}", no)
            vals = to_numbers(np.array(parts), str(path), np.full(len(parts), no), names[0])
            for n, v in zip(names, vals, strict=True):
                out[n].append(float(v))
    res = {k: np.array(v) for k, v in out.items()}
    if np.any(res["ck"] == 0):
        raise ProjectError(str(path), "camera constant ck is zero")
    return res


def _read_scale(path: Path, encoding: str = ENCODING) -> dict:
    out: dict[str, list] = {k: [] for k in ("id", "name", "a", "b", "length", "sigma", "status",
                                          "_lines")}
    if not path.is_file():
        return {k: np.array(v) for k, v in out.items()}
    for no, s in enumerate(whole_lines(path, encoding, allow_empty=True), start=1):
        t = s.strip()
        if not t or t.startswith("#"):
            continue
        first, quote, rest = t.partition('"')
        name, quote2, tail = rest.partition('"')
        if not quote or not quote2:
            raise ProjectError(str(path), 'expected id "name" pointA pointB length sigma status',
                               no)
        parts = first.split() + tail.split()
        if len(parts) != 6:
            raise ProjectError(str(path), 'expected id "name" pointA pointB length sigma status',
                               no)
        vals = to_numbers(np.array(parts), str(path), np.full(6, no), "scale bar")
        if vals[3] <= 0 or vals[4] <= 0:
            raise ProjectError(str(path), "length and sigma must be positive", no)
        for k, v in zip(("id", "a", "b", "length", "sigma", "status"), vals, strict=True):
            out[k].append(v)
        out["name"].append(name)
        out["_lines"].append(no)
    where = [(str(path), n) for n in out["_lines"]]
    refuse_repeats(out["id"], where, lambda i: f"scale bar {point_id(out['id'][i])}", "id")
    refuse_repeats([frozenset((a, b)) for a, b in zip(out["a"], out["b"], strict=True)],
                   where, lambda i: f"a scale bar between points {point_id(out['a'][i])} "
                   f"and {point_id(out['b'][i])}")
    return {k: np.array(v) for k, v in out.items()}


def read_aicon(path: str | Path, encoding: str = ENCODING) -> AiconProject:
    """Read an AICON project given its folder or any of its files (text in `encoding`)."""
    folder, stem = _stem(Path(path))
    f = {e: folder / f"{stem}.{e}" for e in EXTENSIONS}
    cams = _read_ior(f["ior"], encoding)
    images = _table(f["eor"], ["id", "camera", "X0", "Y0", "Z0", "omega", "phi", "kappa",
                               "order", "status", "orient"], ("id", "camera"), encoding)
    points = _table(f["obc"], ["id", "X", "Y", "Z", "sX", "sY", "sZ", "rays", "status", "new",
                               "datum"], (), encoding)
    obs = _table(f["phc"], ["image", "point", "x", "y", "sx", "sy", "vx", "vy", "method",
                            "status", "internal"], ("image",), encoding)
    for what, t, key in (("image", images, "id"), ("point", points, "id")):
        u, first = np.unique(t[key], return_index=True)
        if len(u) != len(t[key]):
            dup = np.setdiff1d(np.arange(len(t[key])), first)[0]
            raise ProjectError(str(f["eor" if what == "image" else "obc"]),
                               f"duplicate {what} id {point_id(t[key][dup])}",
                               int(t["_lines"][dup]), "id")
    # (an observation of a point that .obc does not hold is legitimate: AICON lists the
    # measurements of points it did not compute; so a .obc cut at a line end cannot show)
    bad = np.flatnonzero((obs["status"] > 0) & ~np.isin(obs["image"], images["id"]))
    if len(bad):
        raise ProjectError(str(f["phc"]), f"unknown image {point_id(obs['image'][bad[0]])} "
                           f"({f['eor'].name} holds {len(images['id'])} images: is it cut "
                           "short?)", int(obs["_lines"][bad[0]]), "image")
    low, high = (v * 1e-3 for v in SIGMA_IMAGE_UM)  # µm -> mm
    for name in ("sx", "sy"):
        bad = np.flatnonzero(~((obs[name] >= low) & (obs[name] <= high)))
        if len(bad):
            raise ProjectError(str(f["phc"]), f"standard deviation {obs[name][bad[0]]:g} mm: "
                               f"expected {low:g} to {high:g} mm", int(obs["_lines"][bad[0]]),
                               name)
    # a point measured again on an image: AICON keeps the earlier row with status 0 (the
    # data set does so 6 times); two rows in use are the same measurement counted twice
    used = np.flatnonzero(obs["status"] > 0)
    refuse_repeats(zip(obs["image"][used].tolist(), obs["point"][used].tolist(), strict=True),
                   [(str(f["phc"]), int(n)) for n in obs["_lines"][used]],
                   lambda i: f"point {point_id(obs['point'][used[i]])} on image "
                   f"{point_id(obs['image'][used[i]])} (in use: status > 0)", "point")
    scale = _read_scale(f["scale"], encoding)
    return AiconProject(stem, folder, cams, images, points, obs, scale)
