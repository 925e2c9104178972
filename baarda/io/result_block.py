"""The adjusted block of a result folder of `baarda adjust`, for `baarda convert RESULT --to
FMT`: the run's input read again (summary.json's input path), with the adjusted
orientations (photos.csv), point coordinates (points.csv) and camera constants and
principal points (summary.json's cameras) put in, and the rejected image observations
(observations.csv's `rejected`) left out; these are returned with their w and MDB, for a
side file.  A self-calibration's cameras.csv gives every camera parameter as adjusted (c,
x0, y0 and the lens model's terms), and the model.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.block.photo_block import Block
from baarda.block.rotation import angle_to_rad
from baarda.errors import ProjectError
from baarda.io.run_manifest import written_excel_safe
from baarda.io.table import unquoted_formulas
from baarda.kinds import IMAGE


def is_result_folder(path: str | Path) -> bool:
    p = Path(path)
    return p.is_dir() and (p / "summary.json").is_file() and (p / "run.json").is_file()


def _by_id(ids: list[str], table: pd.DataFrame, column: str, where: Path) -> np.ndarray:
    """The rows of `table` in the order of `ids` (ProjectError naming an id it lacks)."""
    index = {str(v): k for k, v in enumerate(table[column].astype(str))}
    missing = [i for i in ids if i not in index]
    if missing:
        raise ProjectError(str(where), f"{column} {missing[0]} of the input is not in the "
                           "result (was the input changed after the run?)")
    return np.array([index[i] for i in ids], np.int64)


def _calibrated(cams, path: Path):
    """`cams` with every parameter of cameras.csv (camera, model, parameter, value)."""
    from baarda.block.camera_models import MODELS

    t = pd.read_csv(path, dtype={"camera": str})
    if written_excel_safe(path.parent) and "camera" in t:
        t["camera"] = unquoted_formulas(t["camera"].to_numpy(str))
    missing = {"camera", "model", "parameter", "value"} - set(t.columns)
    if missing:
        raise ProjectError(str(path), f"columns {sorted(missing)} missing")
    focal, pp = cams.focal_mm.astype(float).copy(), cams.principal_point_mm.astype(float).copy()
    kinds = (np.full(len(cams), "none", dtype=object) if cams.model is None
             else np.asarray(cams.model, dtype=object).copy())
    width = max([len(MODELS[m].params) for m in set(t["model"])] +
                [0 if cams.coefficients is None else cams.coefficients.shape[1]])
    coef = np.zeros((len(cams), width))
    if cams.coefficients is not None:
        coef[:, :cams.coefficients.shape[1]] = cams.coefficients
    index = {c: i for i, c in enumerate(cams.ids)}
    for row in t.itertuples(index=False):
        i = index.get(str(row.camera))
        if i is None:
            raise ProjectError(str(path), f"camera {row.camera} is not one of the input's")
        if row.model not in MODELS:
            raise ProjectError(str(path), f"camera {row.camera}: unknown model {row.model}")
        if kinds[i] != row.model:
            kinds[i], coef[i] = row.model, 0.0
        if row.parameter == "c":
            focal[i] = row.value
        elif row.parameter in ("x0", "y0"):
            pp[i, row.parameter == "y0"] = row.value
        elif row.parameter in MODELS[row.model].params:
            coef[i, MODELS[row.model].params.index(row.parameter)] = row.value
    return replace(cams, focal_mm=focal, principal_point_mm=pp, model=kinds,
                   coefficients=coef)


def _observed_as_run(block: Block, obs: pd.DataFrame, notes: list[str]) -> Block:
    """The image coordinates as the run had them (observations.csv's x_mm, y_mm: the run
    may have read its input with other options, e.g. --pixel-mm); image observations of the
    input that are not in the result are left out, with a note."""
    img = obs[(obs["kind"] == IMAGE.name) & (obs["component"] == IMAGE.components[0])]
    pairs = pd.DataFrame({"photo": [block.photos.ids[i] for i in block.image.photo],
                          "point": [block.points.ids[j] for j in block.image.point]})
    got = pairs.merge(img[["photo", "point", "x_mm", "y_mm"]].astype(
        {"photo": str, "point": str}).drop_duplicates(["photo", "point"]),
        on=["photo", "point"], how="left")
    xy = got[["x_mm", "y_mm"]].to_numpy(float)
    found = np.isfinite(xy).all(axis=1)
    image = block.image
    given = image.xy_mm[found]
    use = np.abs(given) > 1e-9
    ratio = xy[found][use] / given[use]
    if len(ratio) and np.allclose(ratio, ratio[0], rtol=1e-9, atol=0) and \
            not np.isclose(ratio[0], 1.0, rtol=1e-12, atol=0):
        # the run read its input with another pixel size (--pixel-mm): the writers' pixels
        # are the run's, so that the file has the input's pixel coordinates
        from baarda.io.image_sigma import PIXEL_MM

        c = block.cameras
        px = (np.full(len(c), PIXEL_MM) if c.pixel_mm is None else
              np.where(np.isfinite(c.pixel_mm), c.pixel_mm, PIXEL_MM)) * float(ratio[0])
        frame = None if c.pixel_frame is None else np.asarray(c.pixel_frame, float).copy()
        if frame is not None:
            frame[:, 2:] *= float(ratio[0])
        block = replace(block, cameras=replace(c, pixel_mm=px, pixel_frame=frame))
        notes.append(f"the run's pixel size: {px[0]:g} mm (its input read with --pixel-mm)")
    block = replace(block, image=replace(image, xy_mm=np.where(found[:, None], xy,
                                                               image.xy_mm)))
    if not found.all():
        notes.append(f"{int((~found).sum())} image observation(s) of the input not in the "
                     "result: left out")
        block = block.select_image(found)
    return block


def read_result_block(folder: str | Path, keep_given: bool = False,
                      **read_options) -> tuple[Block, pd.DataFrame]:
    """(adjusted block, rejected observations: photo, point, component, w, mdb).
    keep_given: control and check points keep their given coordinates (for a format that
    holds them as reference coordinates: PAT-B, Metashape; the adjusted ones would make
    the control agree with the result and change sigma0 when adjusted again); else every
    point gets its adjusted ones."""
    from baarda.io.formats import read_any
    from baarda.io.result_folder import read_results

    folder = Path(folder)
    res = read_results(folder)
    source = res.summary.get("source") or (res.summary.get("input") or {}).get("path")
    if not source or not Path(source).exists():
        raise ProjectError(str(folder / "summary.json"), f"the run's input {source!r} is not "
                           "there: the adjusted block is written over its input's "
                           "observations", column="source")
    block = read_any(source, **read_options)
    notes = [f"adjusted orientations, points and cameras of the result folder {folder}"]
    if res.photos is not None and len(block.photos):
        ph = res.photos.iloc[_by_id(block.photos.ids, res.photos, "photo",
                                    folder / "photos.csv")]
        unit = res.angle_unit or block.settings.angle_unit
        ang = angle_to_rad(ph[["omega", "phi", "kappa"]].to_numpy(float), unit)
        eo = np.column_stack([ph[["X0", "Y0", "Z0"]].to_numpy(float), ang])
        block = replace(block, photos=replace(block.photos, eo=eo))
    if res.points is not None:
        used = np.unique(block.image.point)
        if keep_given:
            used = used[block.points.role[used] == "tie"]
        ids = [block.points.ids[j] for j in used]
        pt = res.points.iloc[_by_id(ids, res.points, "point", folder / "points.csv")]
        xyz = block.points.xyz.copy()
        xyz[used] = pt[["X", "Y", "Z"]].to_numpy(float)
        block = replace(block, points=replace(block.points, xyz=xyz))
    cams = res.cameras
    if cams:
        c = block.cameras
        focal, pp = c.focal_mm.astype(float).copy(), c.principal_point_mm.astype(float).copy()
        for i, cid in enumerate(c.ids):
            if cid in cams:
                focal[i] = cams[cid]["focal_mm"]
                pp[i] = cams[cid]["x0_mm"], cams[cid]["y0_mm"]
        block = replace(block, cameras=replace(c, focal_mm=focal, principal_point_mm=pp))
    if (folder / "cameras.csv").is_file():
        block = replace(block, cameras=_calibrated(block.cameras, folder / "cameras.csv"))
        notes.append("the cameras as self-calibrated (cameras.csv)")
    obs = res.obs
    block = _observed_as_run(block, obs, notes)
    rej = obs[(obs["kind"] == IMAGE.name) & obs["rejected"].astype(bool)]  # read as True/False
    rejected = rej[["photo", "point", "component", "w", "mdb"]].reset_index(drop=True)
    if len(rejected):
        pi, qi = block.photo_index, block.point_index
        pairs = {(pi.get(str(a), -1), qi.get(str(b), -1))
                 for a, b in zip(rejected["photo"], rejected["point"], strict=True)}
        drop = np.array([(p, q) in pairs for p, q in zip(block.image.photo.tolist(),
                                                         block.image.point.tolist(),
                                                         strict=True)], bool)
        block = block.select_image(~drop)
        notes.append(f"{int(drop.sum())} rejected image observation(s) left out (listed with "
                     "their w and MDB in rejected.csv)")
    return replace(block, notes=block.notes + notes), rejected
