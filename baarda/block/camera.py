"""A block's cameras seen through their models (block/camera_models.py).

Every camera has the interior orientation c, x0, y0 (mm) of `Cameras` and a model with
coefficients (`Cameras.coefficients`, the model's `params` in order, zero-padded) and
constants (`Cameras.constants`, e.g. AICON's R0, the grid spacing of Ebner's and Gruen's
sets).  Kinds (docs/camera_models.md): ``none``, ``brown``, ``dbat3``, ``dbat5``,
``brown_forward``, ``aicon``, ``ebner``, ``gruen``; ``brown_backward`` is the earlier name of
``brown`` (its five coefficients k1, k2, k3, p1, p2 and b1 = b2 = 0).

* backward models correct the observations: ideal = pp + u + delta(u), u = observed - pp;
* forward models distort the projection: projected = pp + s (u + delta(u)),
  u = (ideal - pp) / s, s = c for normalised models, 1 otherwise.

The parameters a self-calibration estimates per camera ('c', 'x0', 'y0' and any of the
model's params) are no part of the cameras: the block's `settings.calibration_free`, as the
input states them and as the run's configuration resolves them (io/configuration.py).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baarda.block.camera_models import MODELS, CameraModel, get_model, invert
from baarda.options import CALIBRATION_GROUPS  # noqa: F401 (re-exported)

ALIASES = {"brown_backward": "brown"}
KINDS = tuple(MODELS) + tuple(ALIASES)
INTERIOR = ("c", "x0", "y0")
# a reader's note about what the input estimates starts with this: --calibrate replaces it
INPUT_CALIBRATION = "the input's calibration: "


def model_of(kind: str) -> CameraModel:
    """The camera model of a kind (aliases resolved); ValueError for an unknown kind."""
    if kind not in KINDS:
        raise ValueError(f"unknown camera model '{kind}' (known: {', '.join(KINDS)})")
    return get_model(ALIASES.get(kind, kind))


def kinds(cameras) -> np.ndarray:
    """(n,) object array of the model kind of every camera ('none' where not given)."""
    n = len(cameras)
    k = getattr(cameras, "model", None)
    return np.full(n, "none", dtype=object) if k is None else np.asarray(k, dtype=object)


def parameter_names(cameras, i: int) -> tuple[str, ...]:
    """'c', 'x0', 'y0' and the model's params of camera i."""
    return INTERIOR + model_of(kinds(cameras)[i]).params


def coefficients(cameras, i: int) -> np.ndarray:
    """The model coefficients of camera i in its model's order (missing ones 0)."""
    model = model_of(kinds(cameras)[i])
    coef = getattr(cameras, "coefficients", None)
    if coef is None:
        return np.zeros(model.n_params)
    row = np.asarray(coef, float).reshape(len(cameras), -1)[i]
    out = np.zeros(model.n_params)
    out[:min(len(row), model.n_params)] = row[:model.n_params]
    return out


def lens(cameras, i: int) -> tuple[str, np.ndarray]:
    """(kind, coefficients) of camera i: its model kind ('none' where not given) and its
    coefficients in the model's order (kinds, coefficients), for the writers."""
    return str(kinds(cameras)[i]), coefficients(cameras, i)


def constants(cameras, i: int) -> np.ndarray:
    """The model constants of camera i (NaN where not given)."""
    model = model_of(kinds(cameras)[i])
    const = getattr(cameras, "constants", None)
    out = np.full(len(model.constants), np.nan)
    if const is not None and len(model.constants):
        row = np.asarray(const, float).reshape(len(cameras), -1)[i]
        out[:min(len(row), len(out))] = row[:len(out)]
    return out


def parameters(cameras, i: int) -> np.ndarray:
    """[c, x0, y0, coefficients...] of camera i."""
    return np.concatenate([[float(cameras.focal_mm[i])],
                           np.asarray(cameras.principal_point_mm[i], float),
                           coefficients(cameras, i)])


def _table(values, n: int, k: int, fill: float) -> np.ndarray:
    """(n, k): the first k columns of a per-camera table, `fill` where missing."""
    out = np.full((n, k), fill)
    if values is not None and k:
        v = np.asarray(values, float).reshape(n, -1)
        w = min(v.shape[1], k)
        out[:, :w] = v[:, :w]
    return out


def _width(values, n: int) -> int:
    return 0 if values is None else np.asarray(values, float).reshape(n, -1).shape[1]


def with_camera(cameras, other, i: int):
    """`cameras` with camera i of `other` appended (a Cameras; the per-camera tables
    widened to the wider of the two: coefficients 0, constants and pixel sizes NaN where
    one has none)."""
    n, m = len(cameras), len(other)
    kind = np.concatenate([kinds(cameras), kinds(other)[[i]]])
    kc = max(_width(cameras.coefficients, n), _width(other.coefficients, m))
    kk = max(_width(cameras.constants, n), _width(other.constants, m))

    def stacked(a, b, k, fill):
        return np.vstack([_table(a, n, k, fill), _table(b, m, k, fill)[[i]]]) if k else None

    pixel = None
    if cameras.pixel_mm is not None or other.pixel_mm is not None:
        pixel = np.append(_table(cameras.pixel_mm, n, 1, np.nan)[:, 0],
                          _table(other.pixel_mm, m, 1, np.nan)[i, 0])
    return replace(cameras, ids=list(cameras.ids) + [other.ids[i]],
                   focal_mm=np.append(cameras.focal_mm, other.focal_mm[i]),
                   principal_point_mm=np.vstack([cameras.principal_point_mm,
                                                 other.principal_point_mm[[i]]]),
                   model=None if (kind == "none").all() else kind,
                   coefficients=stacked(cameras.coefficients, other.coefficients, kc, 0.0),
                   constants=stacked(cameras.constants, other.constants, kk, np.nan),
                   pixel_mm=pixel,
                   pixel_frame=None if cameras.pixel_frame is None and other.pixel_frame is None
                   else stacked(cameras.pixel_frame, other.pixel_frame, 4, np.nan),
                   image_size_px=None if cameras.image_size_px is None
                   and other.image_size_px is None
                   else stacked(cameras.image_size_px, other.image_size_px, 2, np.nan))


def _cameras_of_side(block, side: str):
    """(model, rows of block.image, and per row its principal point [mm] (m, 2),
    coefficients (m, k), constants (m, c) and camera (m,)) of the cameras with a
    distortion model applied on `side` ("backward": to the observations, "forward": in the
    projection), all cameras of one model at once (a block may have a camera per photo)."""
    cams = block.cameras
    cam = block.photos.camera[block.image.photo]
    kind = kinds(cams)
    for name in dict.fromkeys(kind.tolist()):
        model = model_of(name)
        if model.side != side or not model.n_params:
            continue
        rows = np.flatnonzero((kind == name)[cam])
        if not len(rows):
            continue
        c = cam[rows]
        n = len(cams)
        yield (model, rows, np.asarray(cams.principal_point_mm, float)[c],
               _table(getattr(cams, "coefficients", None), n, model.n_params, 0.0)[c],
               _table(getattr(cams, "constants", None), n, len(model.constants), np.nan)[c],
               c)


def corrected_observations(block) -> np.ndarray:
    """The observations (m, 2) in mm with backward models applied (ideal coordinates);
    rows of forward-model cameras as observed (the projection applies those)."""
    out = np.array(block.image.xy_mm, dtype=float, copy=True)
    for model, rows, pp, coef, const, _ in _cameras_of_side(block, "backward"):
        out[rows] += model.correction(out[rows] - pp, coef, const)[0]
    return out


def ideal_image_coordinates(block) -> np.ndarray:
    """Image coordinates (m, 2) in mm free of distortion, for every row of block.image
    (backward models: the corrected observations; forward models: inverted, camera by
    camera, for approximations only: the adjustment applies them in the projection)."""
    out = corrected_observations(block)
    focal = np.asarray(block.cameras.focal_mm, float)
    for model, rows, pp, coef, const, cam in _cameras_of_side(block, "forward"):
        s = focal[cam][:, None] if model.normalized else 1.0
        out[rows] = pp + s * invert(model, (out[rows] - pp) / s, coef, const, groups=cam)
    return out


def cameras_per_strip(block):
    """The block with one camera for every (camera, strip) pair that its photos use, so that
    a self-calibration estimates each strip's parameters of its own (calibration group
    "strip"); the copies are named "CAMERA/STRIP" and start from their camera's values.  A
    camera used in one strip only keeps its id."""
    cams, ph = block.cameras, block.photos
    strips = np.asarray([str(s) for s in ph.strip], dtype=object)
    pairs: dict[tuple[int, str], int] = {}
    new_camera = np.empty(len(ph), dtype=np.int64)
    for i, (c, s) in enumerate(zip(ph.camera.tolist(), strips.tolist(), strict=True)):
        new_camera[i] = pairs.setdefault((c, s), len(pairs))
    source = np.array([c for c, _ in pairs], dtype=np.int64)
    n_strips = {c: sum(1 for cc, _ in pairs if cc == c) for c, _ in pairs}
    ids = [cams.ids[c] if n_strips[c] == 1 else f"{cams.ids[c]}/{s}" for c, s in pairs]

    def take(a):
        return None if a is None else np.asarray(a)[source]

    new = replace(cams, ids=ids, focal_mm=cams.focal_mm[source],
                  principal_point_mm=cams.principal_point_mm[source], model=take(cams.model),
                  coefficients=take(cams.coefficients), constants=take(cams.constants),
                  pixel_mm=take(cams.pixel_mm), pixel_frame=take(cams.pixel_frame),
                  image_size_px=take(cams.image_size_px))
    free = block.settings.calibration_free
    settings = block.settings if free is None else replace(
        block.settings, calibration_free=tuple(free[c] for c in source))
    return replace(block, cameras=new, photos=replace(ph, camera=new_camera), settings=settings,
                   notes=list(block.notes) + [
                       f"calibration per strip: {len(cams)} camera(s) -> {len(new)} "
                       "(one per camera and strip)"])


def with_camera_model(block, model: str):
    """The block with every camera on camera model `model` (coefficients 0 unless it keeps
    its model; Ebner's and Gruen's grid spacing from the extent of the image points; the
    free parameters cleared: io/configuration.py decides them); ValueError for an unknown
    model or one that needs constants the block lacks."""
    cams = block.cameras
    n = len(cams)
    if model not in KINDS:
        raise ValueError(f"unknown camera model '{model}' (known: {', '.join(KINDS)})")
    new = model_of(model)
    old = kinds(cams)
    coef = np.zeros((n, new.n_params))
    for i in range(n):
        if model_of(old[i]).name == new.name:
            coef[i] = coefficients(cams, i)
    const = np.full((n, len(new.constants)), np.nan)
    if new.name in ("ebner", "gruen"):
        cam = block.photos.camera[block.image.photo]
        for i in range(n):
            xy = block.image.xy_mm[cam == i] - cams.principal_point_mm[i]
            extent = float(np.max(np.abs(xy), initial=1.0))
            const[i, 0] = extent if new.name == "ebner" else extent / 2
    elif new.constants:
        raise ValueError(f"camera model '{model}' needs {', '.join(new.constants)}: give "
                         "it in cameras.csv")
    cams = replace(cams, model=np.full(n, model, dtype=object),
                   coefficients=coef if new.n_params else None,
                   constants=const if new.constants else None)
    return replace(block, cameras=cams,
                   settings=replace(block.settings, calibration_free=None))


def chosen_parameters(cameras, free) -> tuple[tuple[str, ...], ...]:
    """The parameters estimated per camera by `free`: "none", "all" (c, x0, y0 and every
    coefficient of each camera's model) or parameter names for every camera; ValueError
    naming a name that is not a parameter of a camera's model."""
    n = len(cameras)
    if free == "none":
        return ((),) * n
    if free == "all":
        return tuple(INTERIOR + model_of(k).params for k in kinds(cameras))
    names = tuple(free)
    for i in range(n):
        bad = [p for p in names if p not in parameter_names(cameras, i)]
        if bad:
            raise ValueError(f"camera {cameras.ids[i]}: '{bad[0]}' is not a parameter of "
                             f"its model '{kinds(cameras)[i]}' "
                             f"({', '.join(parameter_names(cameras, i))})")
    return (names,) * n


def calibrate_note(free) -> str:
    """The note of a calibration chosen for the run over the input's."""
    what = ("none (every camera's parameters held at the input's values)"
            if free == "none" else "all" if free == "all" else ", ".join(free))
    return f"calibrate {what}: chosen for this run, over what the input sets"


def with_calibration(block, model: str | None = None, free=None):
    """The block with every camera on camera model `model` (with_camera_model; the
    parameters estimated before stay estimated where the new model has them) and with
    `free` estimated (chosen_parameters): a list of parameter names for every camera,
    "none" or "all"; None keeps the block's (readers and project.toml set it).  The API of
    one step; a run resolves its calibration once in io/configuration.py."""
    before = block.settings.calibration_free
    if model is not None:
        block = with_camera_model(block, model)
        if free is None and before is not None:
            names = [set(parameter_names(block.cameras, i)) for i in range(len(before))]
            kept = tuple(tuple(p for p in f if p in names[i]) for i, f in enumerate(before))
            block = replace(block, settings=replace(block.settings, calibration_free=kept))
    if free is None:
        return block
    chosen = chosen_parameters(block.cameras, free)
    return replace(block, settings=replace(block.settings, calibration_free=chosen),
                   notes=[*block.notes, calibrate_note(free)])
