"""The native project format: a folder with project.toml and four CSV files.

See docs/format.md for the contract.  `read_project` validates everything and names the
file, line and column of the first problem; `write_project` writes atomically.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from baarda.block.camera import (
    CALIBRATION_GROUPS,
    INTERIOR,
    KINDS,
    model_of,
    parameter_names,
)
from baarda.block.camera_models import MODELS
from baarda.block.photo_block import (
    Block,
    Cameras,
    Distances,
    GroundPoints,
    ImagePoints,
    Photos,
    Settings,
    no_distances,
)
from baarda.block.rotation import angle_to_rad
from baarda.errors import ProjectError
from baarda.io.gnss_imu_files import gnss_imu_settings, read_gnss, read_imu
from baarda.io.image_sigma import SIGMA_IMAGE_UM, check_sigma_um
from baarda.io.project_toml import (
    KEYS,
    check_keys,
    given_keys,
    load_toml,
    positive_settings,
    toml_table,
)
from baarda.io.table import Table
from baarda.io.text_files import ENCODING
from baarda.kinds import GNSS, IMU
from baarda.options import DATUMS

SIGMA_GROUND_MAX_M = 1e6  # a ground standard deviation beyond 1000 km means nothing (and
# squared beyond 1e154 m it overflows the statistics): leave the coordinate unobserved
FILES = ("project.toml", "cameras.csv", "photos.csv", "image_points.csv", "ground_points.csv")


def _settings(path: Path, encoding: str = ENCODING) -> tuple[Settings, dict]:
    """The settings of project.toml and the document (to tell given from default values)."""
    s = Settings()
    doc, s.angle_unit = load_toml(path, s.angle_unit, encoding)
    for table in ("sigma", "tests", GNSS.name, IMU.name):
        check_keys(toml_table(doc, table, path), path, table)
    check_keys(doc, path)
    s.given = given_keys(doc)
    s.name = str(doc.get("name", path.parent.name))
    unit = str(doc.get("image_unit", "mm"))
    if unit != "mm":
        raise ProjectError(str(path), f"image_unit '{unit}': image coordinates must be in mm",
                           column="image_unit")
    sigma = toml_table(doc, "sigma", path)
    tests = toml_table(doc, "tests", path)
    try:
        s.sigma_image_um = float(sigma.get("image_um", s.sigma_image_um))
        ctrl = sigma.get("control_m", s.sigma_control_m)
        ctrl = [float(ctrl)] * 3 if np.isscalar(ctrl) else [float(c) for c in ctrl]  # type: ignore[arg-type]
        s.alpha0 = float(tests.get("alpha0", s.alpha0))
        s.beta0 = float(tests.get("beta0", s.beta0))
        s.alpha_global = float(tests.get("alpha_global", s.alpha_global))
    except (TypeError, ValueError, OverflowError) as e:
        raise ProjectError(str(path), f"a setting is not a number: {e}") from None
    if len(ctrl) != 3:
        raise ProjectError(str(path), "sigma.control_m must be one number or [X, Y, Z]",
                           column="sigma.control_m")
    positive_settings(path, {"sigma.image_um": s.sigma_image_um})
    positive_settings(path, {f"sigma.control_m[{k}]": c for k, c in enumerate(ctrl)},
                      SIGMA_GROUND_MAX_M)
    check_sigma_um(s.sigma_image_um, str(path), column="sigma.image_um")
    s.sigma_control_m = tuple(ctrl)  # type: ignore[assignment]  # X, Y, Z
    if not 0 < s.alpha_global < 0.5:
        raise ProjectError(str(path), "tests.alpha_global must be in (0, 0.5)",
                           column="tests.alpha_global")
    if not (0 < s.alpha0 < 0.5 and 0.5 <= s.beta0 < 1):
        raise ProjectError(str(path), "tests.alpha0 must be in (0, 0.5) and tests.beta0 in "
                           "[0.5, 1)")
    s.crs = doc.get("crs") or None
    if s.crs is not None and not isinstance(s.crs, str):
        raise ProjectError(str(path), "crs must be a string such as \"EPSG:25832\"",
                           column="crs")
    s.datum = str(doc.get("datum", s.datum))
    if s.datum not in DATUMS:
        raise ProjectError(str(path), f"datum '{s.datum}' is not one of control, free, inner",
                           column="datum")
    return s, doc


def read_ground_points(path: Path, sigma_control_m, encoding: str = ENCODING
                       ) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray, Table]:
    """ground_points.csv of a project or a model project: ids, xyz (k, 3), sigma (k, 3) [m]
    (NaN = not observed; the default sigma_control_m where the columns are missing; a check
    point's: the accuracy of its survey, not an observation, NaN unless the file gives it),
    role (k,) and the table (for line numbers)."""
    g = Table(path, ["point", "X", "Y", "Z", "role"], encoding)
    ids = [str(p) for p in g.unique_ids("point")]
    role = g.text("role")
    for i, r in enumerate(role):
        if r not in ("control", "check", "fixed"):
            raise ProjectError(g.path, f"role '{r}' must be 'control', 'fixed' or 'check'",
                               int(g.lines[i]), "role")
    xyz = np.column_stack([g.numbers(c, allow_empty=True) for c in "XYZ"])
    names = [f"sigma_{c}" for c in "XYZ"]
    given = all(g.has(n) for n in names)
    if given:
        sig = np.column_stack([g.numbers(n, allow_empty=True) for n in names])
    elif any(g.has(n) for n in names):
        raise ProjectError(g.path, "give all three columns sigma_X, sigma_Y, sigma_Z or none")
    else:
        sig = np.tile(np.asarray(sigma_control_m, float), (len(ids), 1))
    fixed = role == "fixed"  # every given coordinate held: sigma 0
    sig[fixed] = np.where(np.isfinite(xyz[fixed]), 0.0, np.nan)
    role = np.where(fixed, "control", role)
    for k, c in enumerate("XYZ"):
        bad = np.flatnonzero(np.isfinite(sig[:, k]) & ~(sig[:, k] >= 0))
        if len(bad):
            raise ProjectError(g.path, "standard deviation must be positive (0: the "
                               "coordinate is fixed)", int(g.lines[bad[0]]), f"sigma_{c}")
        bad = np.flatnonzero(sig[:, k] > SIGMA_GROUND_MAX_M)
        if len(bad):
            raise ProjectError(g.path, f"standard deviation {float(sig[bad[0], k]):g} m: at most "
                               f"{SIGMA_GROUND_MAX_M:g} m (leave it empty: not observed)",
                               int(g.lines[bad[0]]), f"sigma_{c}")
        need = np.isfinite(sig[:, k]) | (role == "check")
        bad = np.flatnonzero(need & ~np.isfinite(xyz[:, k]))
        if len(bad):
            raise ProjectError(g.path, f"coordinate {c} is empty but needed (control with "
                               f"sigma_{c}, or a check point)", int(g.lines[bad[0]]), c)
    ctrl = role == "control"
    bad = np.flatnonzero(ctrl & ~np.isfinite(sig).any(axis=1))
    if len(bad):
        raise ProjectError(g.path, "control point without any standard deviation: nothing "
                           "is controlled", int(g.lines[bad[0]]), "sigma_X")
    sig[~ctrl & ((role != "check") | (not given))] = np.nan
    return ids, xyz, sig, role.astype(object), g


def _camera_models(t: Table, cameras: Cameras) -> Cameras:
    """The `model` column and the columns named as the models' parameters and constants
    (docs/camera_models.md); a coefficient left empty is 0, a constant is required."""
    kinds = t.text("model").astype(object)
    models = []
    for i, k in enumerate(kinds):
        try:
            models.append(model_of(k))
        except ValueError:
            raise ProjectError(t.path, f"camera model '{k}' is not one of {', '.join(KINDS)}",
                               int(t.lines[i]), "model") from None
    width = max([m.n_params for m in models] + [0])
    cwidth = max([len(m.constants) for m in models] + [0])
    coef, const = np.zeros((len(t), width)), np.full((len(t), cwidth), np.nan)
    values: dict[str, np.ndarray] = {}
    for name in {p for m in models for p in m.params + m.constants}:
        if t.has(name):
            values[name] = t.numbers(name, allow_empty=True)
    for i, m in enumerate(models):
        for j, p in enumerate(m.params):
            v = values.get(p, np.zeros(len(t)))[i]
            coef[i, j] = v if np.isfinite(v) else 0.0
        for j, p in enumerate(m.constants):
            v = values.get(p, np.full(len(t), np.nan))[i]
            if not np.isfinite(v):
                raise ProjectError(t.path, f"camera model '{kinds[i]}' needs its constant "
                                   f"'{p}'", int(t.lines[i]), p)
            const[i, j] = v
    return replace(cameras, model=kinds, coefficients=coef,
                   constants=const if cwidth else None)


def _calibration(doc: dict, cameras: Cameras, path: Path) -> tuple[tuple[str, ...], ...] | None:
    """The parameters to estimate per camera from project.toml's [calibration]: `free = [..]`
    for every camera, or a table per camera id with its own `free`.  Each name must be a
    parameter of some camera model here; that it is one of its camera's model is checked
    once the run's camera model is known (io/configuration.py: --camera-model may change
    it)."""
    cal = doc.get("calibration")
    if cal is None:
        return None
    if not isinstance(cal, dict):
        raise ProjectError(str(path), "[calibration] must be a table", column="calibration")
    ids = tuple(str(c) for c in cameras.ids)
    check_keys(cal, path, "calibration", ids, " and a table per camera id ("
               + ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "") + ")")
    known = set(INTERIOR).union(*(m.params for m in MODELS.values()))
    every = cal.get("free", [])
    out = []
    for cid in cameras.ids:
        own = cal.get(cid, {}) if cid not in KEYS["calibration"] else {}
        if isinstance(own, dict):
            for key in own:
                if key != "free":
                    raise ProjectError(str(path), f"unknown key 'calibration.{cid}.{key}': "
                                       f"[calibration.\"{cid}\"] accepts free",
                                       column=f"calibration.{cid}.{key}")
        free = own.get("free", every) if isinstance(own, dict) else every
        if not isinstance(free, list) or not all(isinstance(p, str) for p in free):
            raise ProjectError(str(path), "calibration 'free' must be a list of parameter "
                               "names, e.g. [\"c\", \"x0\", \"y0\", \"k1\"]",
                               column="calibration")
        bad = [p for p in free if p not in known]
        if bad:
            names = parameter_names(cameras, cameras.ids.index(cid))
            raise ProjectError(str(path), f"camera {cid}: '{bad[0]}' is not a parameter of its "
                               f"model ({', '.join(names)}) nor of any other "
                               "(docs/camera_models.md)", column="calibration")
        out.append(tuple(free))
    return tuple(out)


def _image_sigmas(t: Table) -> np.ndarray:
    """(m, 2) a-priori sigmas of x and y in µm from `sigma_um` or `sigma_x_um` and
    `sigma_y_um` (NaN where empty: the project default)."""
    both = [t.has(c) for c in ("sigma_x_um", "sigma_y_um")]
    if any(both) and not all(both):
        raise ProjectError(t.path, "give both sigma_x_um and sigma_y_um (or sigma_um)")
    if all(both) and t.has("sigma_um"):
        raise ProjectError(t.path, "give sigma_um or sigma_x_um and sigma_y_um, not both")
    names = ("sigma_x_um", "sigma_y_um") if all(both) else ("sigma_um", "sigma_um")
    out = np.full((len(t), 2), np.nan)
    for k, name in enumerate(names):
        if t.has(name):
            out[:, k] = t.numbers(name, allow_empty=True)
            bad = np.flatnonzero(np.isfinite(out[:, k]) & ~(out[:, k] > 0))
            if len(bad):
                raise ProjectError(t.path, "standard deviation must be positive",
                                   int(t.lines[bad[0]]), name)
            low, high = SIGMA_IMAGE_UM
            bad = np.flatnonzero(np.isfinite(out[:, k]) & ((out[:, k] < low) |
                                                           (out[:, k] > high)))
            if len(bad):
                check_sigma_um(float(out[bad[0], k]), t.path, int(t.lines[bad[0]]), name)
    return out


def read_project(folder: str | Path, encoding: str = ENCODING) -> Block:
    """Read and validate a project folder; see docs/format.md.  encoding: of its text
    files (default UTF-8, with or without a byte-order mark).  project.toml's
    [calibration] group is in settings.calibration_group (pipeline.read applies it)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ProjectError(str(folder), "not a project folder")
    settings, doc = _settings(folder / "project.toml", encoding)
    gi = gnss_imu_settings(doc, folder / "project.toml", settings)
    gnss_sigma, imu_sigma = gi.pop("gnss_sigma"), gi.pop("imu_sigma")
    settings = replace(settings, **gi)
    notes: list[str] = []

    t = Table(folder / "cameras.csv", ["camera", "focal_mm", "x0_mm", "y0_mm"], encoding)
    cam_ids = t.unique_ids("camera")
    focal = t.numbers("focal_mm")
    bad = np.flatnonzero(focal <= 0)
    if len(bad):
        raise ProjectError(t.path, "focal length must be positive", int(t.lines[bad[0]]),
                           "focal_mm")
    cameras = Cameras(cam_ids, focal, np.column_stack([t.numbers("x0_mm"), t.numbers("y0_mm")]))
    if t.has("model"):  # optional camera model (block/camera.py), coefficients default 0
        cameras = _camera_models(t, cameras)
    if not cam_ids:
        raise ProjectError(t.path, "no cameras")
    settings = replace(settings, calibration_free=_calibration(doc, cameras,
                                                                folder / "project.toml"))

    t = Table(folder / "photos.csv",
              ["photo", "camera", "strip", "X0", "Y0", "Z0", "omega", "phi", "kappa"], encoding)
    photo_ids = t.unique_ids("photo")
    cam = t.lookup("camera", {c: i for i, c in enumerate(cam_ids)}, "camera")
    eo_cols = ("X0", "Y0", "Z0", "omega", "phi", "kappa")
    eo = np.column_stack([t.numbers(c, allow_empty=True) for c in eo_cols])
    part = np.flatnonzero(np.isnan(eo).any(axis=1) & ~np.isnan(eo).all(axis=1))
    if len(part):  # all six empty: no approximation (the pipeline resects the photo)
        c = eo_cols[int(np.flatnonzero(np.isnan(eo[part[0]]))[0])]
        raise ProjectError(t.path, "give all six orientation values or none (none: "
                           "approximations by space resection)", int(t.lines[part[0]]), c)
    eo[:, 3:] = angle_to_rad(eo[:, 3:], settings.angle_unit)
    photos = Photos(photo_ids, cam, t.text("strip", allow_empty=True).astype(object), eo)
    if not photo_ids:
        raise ProjectError(t.path, "no photos")

    gids, gxyz, gsig, role, g = read_ground_points(folder / "ground_points.csv",
                                                   settings.sigma_control_m, encoding)

    t = Table(folder / "image_points.csv", ["photo", "point", "x_mm", "y_mm"], encoding)
    if len(t) == 0:
        raise ProjectError(t.path, "no image points (the file holds only its header)")
    photo = t.lookup("photo", {p: i for i, p in enumerate(photo_ids)}, "photo")
    pcode, pnames = t.codes("point")
    xy = np.column_stack([t.numbers("x_mm"), t.numbers("y_mm")])
    sig_xy = _image_sigmas(t)  # (m, 2) µm, NaN: the default
    defaulted = int(np.isnan(sig_xy).any(axis=1).sum())
    sig_xy = np.where(np.isfinite(sig_xy), sig_xy, settings.sigma_image_um)
    sig_um = np.sqrt(0.5 * (sig_xy**2).sum(axis=1))
    given = doc.get("sigma", {}) if isinstance(doc.get("sigma"), dict) else {}
    if defaulted and "image_um" not in given:
        notes.append(f"a-priori image sigma {settings.sigma_image_um:g} µm (the default) for "
                     f"{defaulted} image point(s): project.toml has no [sigma] image_um and "
                     "image_points.csv no sigma_um")
    if (role == "control").any() and "control_m" not in given and not g.has("sigma_X"):
        notes.append("a-priori control sigmas X, Y, Z "
                     + "/".join(f"{v:g}" for v in settings.sigma_control_m) + " m (the "
                     "default): project.toml has no [sigma] control_m and ground_points.csv "
                     "no sigma columns")

    # every point: ground file points first, then tie points in order of appearance
    import pandas as pd  # here: a command that fails earlier does not pay for it

    of_name = pd.Index(gids).get_indexer(pnames) if len(pnames) else np.zeros(0, np.int64)
    tie = np.flatnonzero(of_name < 0)  # pnames are in order of first appearance
    of_name[tie] = len(gids) + np.arange(len(tie))
    ids = list(gids) + [pnames[k] for k in tie]
    point = of_name[pcode] if len(pcode) else np.zeros(0, np.int64)
    model = t.text("model", allow_empty=True).astype(object) if t.has("model") else None
    key = photo * len(ids) + point
    if model is not None:  # stereo mode: twin rays of one photo differ in their model
        _, mcode = np.unique(model.astype(str), return_inverse=True)
        key = key * (int(mcode.max(initial=0)) + 1) + mcode
    if len(key) and np.any(np.diff(np.sort(key)) == 0):  # the rows only when there are some
        order = np.argsort(key, kind="stable")
        dup = np.flatnonzero(np.diff(key[order]) == 0)
        i = order[dup[0] + 1]
        raise ProjectError(t.path, f"point '{ids[point[i]]}' measured twice on photo "
                           f"'{photo_ids[photo[i]]}'" + (" in the same model" if model is not
                           None else " (give a 'model' column for stereo twin rays)") +
                           f" (first on line {int(t.lines[order[dup[0]]])})",
                           int(t.lines[i]), "point")
    n_tie = len(ids) - len(gids)
    xyz = np.vstack([gxyz, np.full((n_tie, 3), np.nan)])
    sigma = np.vstack([gsig, np.full((n_tie, 3), np.nan)])
    roles = np.concatenate([role.astype(object), np.full(n_tie, "tie", dtype=object)])
    points = GroundPoints(ids, xyz, sigma, roles)
    per_axis = None if np.array_equal(sig_xy[:, 0], sig_xy[:, 1]) else sig_xy * 1e-3
    image = ImagePoints(photo, point, xy, sig_um * 1e-3, model, per_axis)
    dist = folder / "distances.csv"
    distances = (read_distances(dist, ids, float(doc.get("sigma", {}).get("distance_m", 0.001))
                                if isinstance(doc.get("sigma"), dict) else 0.001, encoding)
                 if dist.is_file() else no_distances())
    gnss = read_gnss(folder / "gnss.csv", photo_ids, gnss_sigma, encoding)
    imu = read_imu(folder / "imu.csv", photo_ids, settings.angle_unit, imu_sigma, encoding)
    settings = replace(settings, calibration_group=_calibration_group(
        doc, folder / "project.toml"))
    return Block(settings, cameras, photos, image, points, source=str(folder), notes=notes,
                 distances=distances, gnss=gnss, imu=imu)


def _calibration_group(doc: dict, path: Path) -> str:
    """[calibration] group: "camera" (default; the parameters of a camera are shared by all
    its photos) or "strip" (estimated per camera and strip)."""
    cal = doc.get("calibration", {})
    group = cal.get("group", "camera") if isinstance(cal, dict) else "camera"
    if group not in CALIBRATION_GROUPS:
        raise ProjectError(str(path), f"calibration group '{group}' is not one of "
                           f"{', '.join(CALIBRATION_GROUPS)}", column="calibration")
    return group


def read_distances(path: Path, point_ids: list[str], default_sigma_m: float,
                   encoding: str = ENCODING) -> Distances:
    """distances.csv: `point_from, point_to, distance_m` and optionally `sigma_m` (empty:
    `default_sigma_m`, project.toml [sigma] distance_m) and `name`."""
    t = Table(path, ["point_from", "point_to", "distance_m"], encoding)
    index = {p: i for i, p in enumerate(point_ids)}
    a = t.lookup("point_from", index, "point")
    b = t.lookup("point_to", index, "point")
    same = np.flatnonzero(a == b)
    if len(same):
        raise ProjectError(t.path, "a distance from a point to itself", int(t.lines[same[0]]),
                           "point_to")
    length = t.numbers("distance_m")
    bad = np.flatnonzero(~(length > 0))
    if len(bad):
        raise ProjectError(t.path, "distance must be positive", int(t.lines[bad[0]]),
                           "distance_m")
    sig = (t.numbers("sigma_m", allow_empty=True) if t.has("sigma_m")
           else np.full(len(t), np.nan))
    bad = np.flatnonzero(np.isfinite(sig) & ~((sig > 0) & (sig <= SIGMA_GROUND_MAX_M)))
    if len(bad):
        raise ProjectError(t.path, f"standard deviation must be positive, at most "
                           f"{SIGMA_GROUND_MAX_M:g} m", int(t.lines[bad[0]]), "sigma_m")
    sig = np.where(np.isfinite(sig), sig, default_sigma_m)
    names = (list(t.text("name", allow_empty=True)) if t.has("name") else
             [f"{point_ids[i]}-{point_ids[j]}" for i, j in zip(a, b, strict=True)])
    return Distances(names, a.astype(np.int64), b.astype(np.int64), length, sig)
