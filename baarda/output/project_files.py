"""Writing projects: the native project folder and the model project folder.

The inverse of baarda.io.project.read_project and baarda.io.model_project.read_model_project
(docs/format.md); a folder is written as one run (output/run_folder.py).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from baarda.block.camera import coefficients, constants, model_of
from baarda.block.camera import kinds as camera_kinds
from baarda.block.crs import delocalize
from baarda.block.model_block import ModelBlock
from baarda.block.photo_block import Block
from baarda.block.rotation import rad_to_angle
from baarda.output.atomic import write_text
from baarda.output.run_folder import RunFolder, staged
from baarda.output.tables import spreadsheet_cell


def format_number(x: float) -> str:
    """A CSV field: the shortest exact repr, empty for NaN (an unobserved coordinate)."""
    return "" if not np.isfinite(x) else repr(float(x))


def write_ground_points(path: Path, ids: list[str], xyz: np.ndarray, sigma: np.ndarray,
                        role: np.ndarray, cell: Callable[[str], str] = str) -> None:
    """ground_points.csv of a project or a model project: control and check points; `cell`
    writes an id (spreadsheet_cell with --excel-safe)."""
    rows = ["point,X,Y,Z,sigma_X,sigma_Y,sigma_Z,role"]
    for j in np.flatnonzero(role != "tie"):
        rows.append(",".join([cell(ids[j])] + [format_number(v) for v in xyz[j]] +
                             [format_number(v) for v in sigma[j]] + [str(role[j])]))
    write_text(path, "\n".join(rows) + "\n")


def cameras_csv(c, cell: Callable[[str], str] = str) -> str:
    """cameras.csv: interior orientation, and with any camera model the `model` column and
    one column per parameter or constant name of the models used (empty where a camera's
    model has no such parameter)."""
    kinds = camera_kinds(c)
    lens = bool(np.any(kinds != "none"))
    names: list[str] = []
    for k in kinds:
        m = model_of(k)
        names += [p for p in m.params + m.constants if p not in names]
    rows = ["camera,focal_mm,x0_mm,y0_mm" + (",model" + "".join(f",{n}" for n in names)
                                             if lens else "")]
    for i in range(len(c)):
        row = (f"{cell(c.ids[i])},{float(c.focal_mm[i])!r},{float(c.principal_point_mm[i, 0])!r},"
               f"{float(c.principal_point_mm[i, 1])!r}")
        if lens:
            m = model_of(kinds[i])
            value = dict(zip(m.params, coefficients(c, i), strict=True))
            value.update(zip(m.constants, constants(c, i), strict=True))
            row += f",{kinds[i]}" + "".join(
                f",{float(value[n])!r}" if n in value else "," for n in names)
        rows.append(row)
    return "\n".join(rows) + "\n"


def write_project(block: Block, folder: str | Path | RunFolder) -> None:
    """Write `block` as a native project folder, one run (output/run_folder.py)."""
    with staged(folder) as run:
        _write_project(block, run.path, spreadsheet_cell if run.excel_safe else str)


def _write_project(block: Block, folder: Path, cell: Callable[[str], str]) -> None:
    """The project's files; `cell` writes an id or other text cell."""
    if block.frame is not None:  # held in a local frame (OpenSfM): write the CRS's numbers
        block = delocalize(block)
    s = block.settings
    toml = [f'name = "{s.name}"', f'angle_unit = "{s.angle_unit}"', 'image_unit = "mm"']
    if s.crs:
        toml.append(f'crs = "{s.crs}"')
    if s.datum != "control":
        toml.append(f'datum = "{s.datum}"')
    toml += ["", "[sigma]", f"image_um = {s.sigma_image_um!r}",
             f"control_m = [{', '.join(repr(float(c)) for c in s.sigma_control_m)}]",
             "", "[tests]", f"alpha0 = {s.alpha0!r}", f"beta0 = {s.beta0!r}", ""]
    c = block.cameras
    free = s.calibration_free
    if free is not None and any(free):  # the parameters a self-calibration estimates
        for i, cid in enumerate(c.ids):
            names = ", ".join(f'"{p}"' for p in free[i])
            toml += [f'[calibration."{cid}"]', f"free = [{names}]", ""]
    if len(block.gnss):
        toml += ["[gnss]", f"lever_arm = [{', '.join(repr(float(v)) for v in s.gnss_lever_arm)}]",
                 f'offsets = "{s.gnss_offsets}"', f"drift = {str(s.gnss_drift).lower()}", ""]
    if len(block.imu):
        toml += ["[imu]", f'boresight = "{s.imu_boresight}"', ""]
    write_text(folder / "project.toml", "\n".join(toml))
    write_text(folder / "cameras.csv", cameras_csv(c, cell))
    p = block.photos
    ang = rad_to_angle(p.eo[:, 3:], s.angle_unit)
    rows = ["photo,camera,strip,X0,Y0,Z0,omega,phi,kappa"] + [
        ",".join([cell(p.ids[i]), cell(c.ids[p.camera[i]]), cell(str(p.strip[i]))] +
                 [format_number(v) for v in p.eo[i, :3]] + [format_number(v) for v in ang[i]])
        for i in range(len(p))]
    write_text(folder / "photos.csv", "\n".join(rows) + "\n")
    im, pts = block.image, block.points
    has_model = im.model is not None
    xy = im.xy_mm.tolist()
    per_axis = im.sigma_xy_mm is not None
    sig = ([f"{sx * 1e3:.6g},{sy * 1e3:.6g}" for sx, sy in im.sigma_xy_mm.tolist()]
           if im.sigma_xy_mm is not None else [f"{s * 1e3:.6g}" for s in im.sigma_mm.tolist()])
    head = "photo,point,x_mm,y_mm," + ("sigma_x_um,sigma_y_um" if per_axis else "sigma_um")
    rows = [head + (",model" if has_model else "")] + [
        f"{cell(p.ids[im.photo[i]])},{cell(pts.ids[im.point[i]])},{xy[i][0]!r},{xy[i][1]!r},{sig[i]}"
        + (f",{im.model[i]}" if im.model is not None else "")
        for i in range(len(im))]
    write_text(folder / "image_points.csv", "\n".join(rows) + "\n")
    write_ground_points(folder / "ground_points.csv", pts.ids, pts.xyz, pts.sigma, pts.role,
                        cell)
    d = block.distances
    if len(d):
        rows = ["name,point_from,point_to,distance_m,sigma_m"] + [
            f"{cell(d.ids[i])},{cell(pts.ids[d.point_a[i]])},{cell(pts.ids[d.point_b[i]])},"
            f"{float(d.length_m[i])!r},{float(d.sigma_m[i])!r}" for i in range(len(d))]
        write_text(folder / "distances.csv", "\n".join(rows) + "\n")
    _write_gnss_imu(block, folder, cell)


def _write_gnss_imu(block: Block, folder: Path, cell: Callable[[str], str]) -> None:
    """gnss.csv and imu.csv (docs/format.md) when the block has such observations."""
    ids = block.photos.ids
    g = block.gnss
    if len(g):
        t = g.time is not None
        rows = ["photo,X,Y,Z,sigma_X,sigma_Y,sigma_Z" + (",time" if t else "")] + [
            ",".join([cell(ids[g.photo[i]])] + [format_number(v) for v in g.xyz[i]]
                     + [repr(float(v)) for v in g.sigma[i]]
                     + ([repr(float(g.time[i]))] if g.time is not None else []))
            for i in range(len(g))]
        write_text(folder / "gnss.csv", "\n".join(rows) + "\n")
    m = block.imu
    if len(m):
        unit = block.settings.angle_unit
        ang, sig = rad_to_angle(m.angles, unit), rad_to_angle(m.sigma, unit)
        rows = ["photo,omega,phi,kappa,sigma_omega,sigma_phi,sigma_kappa"] + [
            ",".join([cell(ids[m.photo[i]])] + [repr(float(v)) for v in ang[i]]
                     + [repr(float(v)) for v in sig[i]]) for i in range(len(m))]
        write_text(folder / "imu.csv", "\n".join(rows) + "\n")


def write_model_project(block: ModelBlock, folder: str | Path | RunFolder) -> None:
    """Write `block` as a model project folder, one run (output/run_folder.py)."""
    with staged(folder) as run:
        _write_model_project(block, run.path)


def _write_model_project(block: ModelBlock, folder: Path) -> None:
    s = block.settings
    toml = [f'name = "{s.name}"', f'angle_unit = "{s.angle_unit}"', "", "[sigma]",
            f"model_xy_um = {float(s.sigma_model_um[0])!r}",
            f"model_z_um = {float(s.sigma_model_um[1])!r}",
            f"control_m = [{', '.join(repr(float(c)) for c in s.sigma_control_m)}]", "",
            "[tests]", f"alpha0 = {s.alpha0!r}", f"beta0 = {s.beta0!r}", "", "[models]",
            f"pre_xy_um = {float(s.pre_um[0])!r}", f"pre_z_um = {float(s.pre_um[1])!r}", ""]
    write_text(folder / "project.toml", "\n".join(toml))
    head = "model,strip,point,kind,x_mm,y_mm,z_mm,sigma_x_um,sigma_y_um,sigma_z_um"
    cov = block.obs_cov
    if cov is not None:
        head += ",rho_xy,rho_xz,rho_yz"
    rows = [head]
    sig = block.obs_sigma * 1e3
    for i in range(len(block.obs_model)):
        m, j = block.obs_model[i], block.obs_point[i]
        vals = [block.models[m], str(block.strip[m]), block.points[j],
                "pc" if block.pc[j] else "point"]
        vals += [format_number(v) for v in block.obs_xyz[i]] + [f"{v:.6g}" for v in sig[i]]
        if cov is not None:
            d = np.sqrt(np.diagonal(cov[i]))
            vals += [f"{cov[i][a, b] / (d[a] * d[b]):.9g}" for a, b in ((0, 1), (0, 2), (1, 2))]
        rows.append(",".join(vals))
    write_text(folder / "models.csv", "\n".join(rows) + "\n")
    write_ground_points(folder / "ground_points.csv", block.points, block.xyz, block.sigma,
                        block.role)
