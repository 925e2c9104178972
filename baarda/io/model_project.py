"""Model projects: project.toml, models.csv (model coordinates) and ground_points.csv.

models.csv, one row per point per model (docs/independent_models.md):

    model, point, x_mm, y_mm, z_mm                     required (z_mm may be empty: 2D only)
    strip                                              optional, one label per model
    kind                                               optional: point (default) or pc
    sigma_xy_um, sigma_z_um  | sigma_x_um, sigma_y_um, sigma_z_um     optional
    rho_xy, rho_xz, rho_yz                             optional correlations (full 3x3)

ground_points.csv has the columns of the bundle project (point, X, Y, Z, role and optional
sigma_X, sigma_Y, sigma_Z in m; role control or check).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from baarda.block.model_block import ModelBlock, ModelSettings
from baarda.errors import ProjectError
from baarda.io.project import read_ground_points
from baarda.io.project_toml import check_keys, load_toml, toml_table
from baarda.io.table import Table
from baarda.io.text_files import ENCODING


def _positive(values, name: str) -> tuple[float, ...]:
    vals = tuple(float(v) for v in values)
    if not all(np.isfinite(v) and v > 0 for v in vals):
        raise ValueError(f"{name} must be finite positive numbers")
    return vals


# the keys a model project's project.toml accepts, by table ("": its top)
MODEL_KEYS = {"": ("name", "angle_unit", "sigma", "tests", "models"),
              "sigma": ("model_xy_um", "model_z_um", "control_m"),
              "tests": ("alpha0", "beta0"),
              "models": ("pre_xy_um", "pre_z_um")}


def read_settings(path: Path, encoding: str = ENCODING) -> ModelSettings:
    """Read project.toml of a model project (missing keys take FOTEF's defaults)."""
    s = ModelSettings()
    doc, s.angle_unit = load_toml(path, s.angle_unit, encoding)
    s.name = str(doc.get("name", path.parent.name))
    sig = toml_table(doc, "sigma", path)
    tests = toml_table(doc, "tests", path)
    pre = toml_table(doc, "models", path)
    for name, table in (("sigma", sig), ("tests", tests), ("models", pre)):
        check_keys(table, path, name, keys=MODEL_KEYS)
    check_keys(doc, path, keys=MODEL_KEYS)
    try:
        s.sigma_model_um = _positive((sig.get("model_xy_um", s.sigma_model_um[0]),  # type: ignore[assignment]
                                      sig.get("model_z_um", s.sigma_model_um[1])),
                                     "sigma.model_xy_um / model_z_um")
        ctrl = sig.get("control_m", s.sigma_control_m)
        ctrl = [ctrl] * 3 if np.isscalar(ctrl) else list(ctrl)
        if len(ctrl) != 3:
            raise ValueError("sigma.control_m must be one number or [X, Y, Z]")
        s.sigma_control_m = _positive(ctrl, "sigma.control_m")  # type: ignore[assignment]
        s.alpha0 = float(tests.get("alpha0", s.alpha0))
        s.beta0 = float(tests.get("beta0", s.beta0))
        s.pre_um = _positive((pre.get("pre_xy_um", s.pre_um[0]),  # type: ignore[assignment]
                              pre.get("pre_z_um", s.pre_um[1])), "models.pre_xy_um / pre_z_um")
    except (TypeError, ValueError, OverflowError) as e:
        raise ProjectError(str(path), f"bad setting: {e}") from None
    if not (0 < s.alpha0 < 0.5 and 0.5 <= s.beta0 < 1):
        raise ProjectError(str(path), "tests.alpha0 must be in (0, 0.5) and tests.beta0 in "
                           "[0.5, 1)")
    return s


def _sigmas(t: Table, settings: ModelSettings) -> np.ndarray:
    """(m, 3) standard deviations in µm from the optional columns."""
    n = len(t)
    default = np.tile([settings.sigma_model_um[0]] * 2 + [settings.sigma_model_um[1]], (n, 1))
    cols = {}
    for name in ("sigma_xy_um", "sigma_z_um", "sigma_x_um", "sigma_y_um"):
        if t.has(name):
            cols[name] = t.numbers(name, allow_empty=True)
    if "sigma_xy_um" in cols and ("sigma_x_um" in cols or "sigma_y_um" in cols):
        raise ProjectError(t.path, "give sigma_xy_um or sigma_x_um/sigma_y_um, not both")
    out = default.copy()
    for k, name in ((0, "sigma_x_um"), (1, "sigma_y_um")):
        if name in cols:
            out[:, k] = np.where(np.isfinite(cols[name]), cols[name], out[:, k])
    if "sigma_xy_um" in cols:
        for k in (0, 1):
            out[:, k] = np.where(np.isfinite(cols["sigma_xy_um"]), cols["sigma_xy_um"], out[:, k])
    if "sigma_z_um" in cols:
        out[:, 2] = np.where(np.isfinite(cols["sigma_z_um"]), cols["sigma_z_um"], out[:, 2])
    for name, c in cols.items():
        bad = np.flatnonzero(np.isfinite(c) & ~(c > 0))
        if len(bad):
            raise ProjectError(t.path, "standard deviation must be positive",
                               int(t.lines[bad[0]]), name)
    return out


def read_model_coordinates(path: Path, settings: ModelSettings, point_ids: list[str],
                           encoding: str = ENCODING):
    """Rows of models.csv; new point ids are appended to `point_ids` (tie points)."""
    t = Table(path, ["model", "point", "x_mm", "y_mm", "z_mm"], encoding)
    if len(t) == 0:
        raise ProjectError(t.path, "no model coordinates")
    model_names = t.text("model")
    models: list[str] = []
    mindex: dict[str, int] = {}
    obs_model = np.empty(len(t), np.int64)
    for i, m in enumerate(model_names):
        j = mindex.get(m)
        if j is None:
            j = mindex[m] = len(models)
            models.append(str(m))
        obs_model[i] = j
    index = {p: i for i, p in enumerate(point_ids)}
    ids = list(point_ids)
    obs_point = np.empty(len(t), np.int64)
    for i, p in enumerate(t.text("point")):
        j = index.get(p)
        if j is None:
            j = index[p] = len(ids)
            ids.append(str(p))
        obs_point[i] = j
    key = obs_model * len(ids) + obs_point
    order = np.argsort(key, kind="stable")
    dup = np.flatnonzero(np.diff(key[order]) == 0)
    if len(dup):
        i = order[dup[0] + 1]
        raise ProjectError(t.path, f"point '{ids[obs_point[i]]}' given twice in model "
                           f"'{models[obs_model[i]]}' (first on line "
                           f"{int(t.lines[order[dup[0]]])})", int(t.lines[i]), "point")
    xyz = np.column_stack([t.numbers("x_mm"), t.numbers("y_mm"),
                           t.numbers("z_mm", allow_empty=True)])
    strip = np.array(["1"] * len(models), dtype=object)
    if t.has("strip"):
        s = t.text("strip", allow_empty=True)
        seen: dict[int | np.integer, tuple[str, int]] = {}
        for i, (m, lab) in enumerate(zip(obs_model, s, strict=True)):
            if m in seen and seen[m][0] != lab:
                raise ProjectError(t.path, f"model '{models[m]}' has strip '{seen[m][0]}' on "
                                   f"line {seen[m][1]} and '{lab}' here", int(t.lines[i]), "strip")
            seen.setdefault(m, (lab, int(t.lines[i])))
        for m, (lab, _) in seen.items():
            strip[m] = lab
    pc = np.zeros(len(ids), bool)
    if t.has("kind"):
        kind = t.text("kind", allow_empty=True)
        first: dict[int, tuple[bool, int]] = {}
        for i, k in enumerate(kind):
            if k not in ("", "point", "pc"):
                raise ProjectError(t.path, f"kind '{k}' must be 'point' or 'pc'",
                                   int(t.lines[i]), "kind")
            j, is_pc = obs_point[i], k == "pc"
            if j in first and first[j][0] != is_pc:
                raise ProjectError(t.path, f"point '{ids[j]}' is a projection centre on line "
                                   f"{first[j][1]} or here but not on both", int(t.lines[i]),
                                   "kind")
            first.setdefault(j, (is_pc, int(t.lines[i])))
            pc[j] = is_pc
    sig = _sigmas(t, settings) * 1e-3
    cov = None
    rho_names = ("rho_xy", "rho_xz", "rho_yz")
    if any(t.has(n) for n in rho_names):
        rho = np.column_stack([t.numbers(n, allow_empty=True) if t.has(n) else np.zeros(len(t))
                               for n in rho_names])
        rho = np.nan_to_num(rho)
        for k, n in enumerate(rho_names):
            bad = np.flatnonzero(np.abs(rho[:, k]) >= 1)
            if len(bad):
                raise ProjectError(t.path, "correlation must be in (-1, 1)",
                                   int(t.lines[bad[0]]), n)
        corr = np.repeat(np.eye(3)[None], len(t), axis=0)
        for k, (a, b) in enumerate(((0, 1), (0, 2), (1, 2))):
            corr[:, a, b] = corr[:, b, a] = rho[:, k]
        cov = corr * sig[:, :, None] * sig[:, None, :]
        bad = np.flatnonzero(np.linalg.eigvalsh(corr)[:, 0] <= 1e-9)
        if len(bad):
            raise ProjectError(t.path, "the correlations give no positive definite "
                               "covariance matrix", int(t.lines[bad[0]]), "rho_xy")
    return models, strip, ids, pc, obs_model, obs_point, xyz, sig, cov, t


def read_model_project(folder: str | Path, encoding: str = ENCODING) -> ModelBlock:
    """Read a model project folder (project.toml, models.csv, ground_points.csv); encoding:
    of its text files (default UTF-8)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ProjectError(str(folder), "not a project folder")
    settings = read_settings(folder / "project.toml", encoding)
    gpath = folder / "ground_points.csv"
    if gpath.is_file():
        gids, gxyz, gsig, grole, _ = read_ground_points(gpath, settings.sigma_control_m,
                                                        encoding)
    else:
        gids, gxyz, gsig, grole = [], np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, object)
    (models, strip, ids, pc, om, op, oxyz, osig, cov,
     t) = read_model_coordinates(folder / "models.csv", settings, list(gids), encoding)
    n_new = len(ids) - len(gids)
    xyz = np.vstack([gxyz, np.full((n_new, 3), np.nan)])
    sigma = np.vstack([gsig, np.full((n_new, 3), np.nan)])
    role = np.concatenate([grole, np.full(n_new, "tie", dtype=object)])
    notes = []
    used = np.bincount(op, minlength=len(ids)) > 0
    for j in np.flatnonzero(~used):
        notes.append(f"{role[j]} point {ids[j]} is in no model: left out")
    z_missing = ~np.isfinite(oxyz[:, 2])
    if z_missing.any() and not z_missing.all():
        notes.append(f"{int(z_missing.sum())} model point(s) without z: planimetry only")
    block = ModelBlock(settings, models, strip, ids, role, pc, xyz, sigma, om, op, oxyz, osig,
                       cov, source=str(folder), notes=notes)
    return drop_unused(block)


def drop_unused(block: ModelBlock) -> ModelBlock:
    """The block without points that are in no model."""
    used = np.bincount(block.obs_point, minlength=block.n_points) > 0
    if used.all():
        return block
    remap = np.cumsum(used) - 1
    return replace(block, points=[p for p, u in zip(block.points, used, strict=True) if u],
                   role=block.role[used], pc=block.pc[used], xyz=block.xyz[used],
                   sigma=block.sigma[used], obs_point=remap[block.obs_point])
