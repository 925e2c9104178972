"""Simulated independent-model blocks with known truth.

The geometry comes from baarda.simulate.aerial: a regular block of vertical photos, ground
points on the pattern grid, control on the perimeter and height chains.  Each stereo pair of
consecutive photos of a strip forms a model; the true terrain points seen on both photos are
transformed into the model frame (origin at the left projection centre, rotation kappa +
small tilts, scale 1 : image scale, so model coordinates are in mm at image scale) and the
projection centres of both photos are added as points.  Noise, gross errors and systematic
model deformations (block-invariant, per strip) are planted on request.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from baarda.block.rotation import rotation_matrix
from baarda.models.independent.data import ModelBlock, ModelSettings
from baarda.simulate.aerial import FlightPlan, simulate_block


@dataclass
class ModelPlan:
    """A simulated model block (FOTEF's study: image scale 1:5000, 10 µm, control 5 cm)."""

    strips: int = 2
    models_per_strip: int = 4
    image_scale: float = 5_000.0
    focal_mm: float = 153.0
    format_mm: float = 230.0
    forward_overlap: float = 0.60
    side_overlap: float = 0.25  # single coverage
    control_spacing: int = 2  # planimetric control on the long borders every k bases
    height_chains: int = 3  # strings of height points across the strips every k bases
    full_control: bool = False  # the border points are XYZ control (else XY only)
    relief_m: float = 0.0
    sigma_model_um: tuple[float, float] = (10.0, 15.0)  # xy, z
    sigma_control_m: tuple[float, float, float] = (0.05, 0.05, 0.05)
    tilt_rad: float = 0.0  # standard deviation of the model tilts (omega, phi)
    kappa_rad: float = 0.3  # standard deviation of the model frame rotation kappa
    projection_centres: bool = True
    noise: bool = True
    blunders: int = 0
    blunder_sigma: tuple[float, float] = (10.0, 30.0)
    deformations: dict = field(default_factory=dict)  # name -> size in µm (block-invariant)
    seed: int = 0
    name: str = "simulated models"


def simulate_models(plan: ModelPlan) -> tuple[ModelBlock, dict]:
    """Simulate a model block; returns (block with noisy observations, truth)."""
    from baarda.models.independent.deformations import deformation_rows

    rng = np.random.default_rng(plan.seed)
    fp = FlightPlan(strips=plan.strips, photos_per_strip=plan.models_per_strip + 1,
                    forward_overlap=plan.forward_overlap, side_overlap=plan.side_overlap,
                    image_scale=plan.image_scale, focal_mm=plan.focal_mm,
                    format_mm=plan.format_mm, pattern=3, control="none", height_chains=0,
                    relief_m=plan.relief_m, noise=False, seed=plan.seed)
    blk, truth = simulate_block(fp)
    pts_true = np.array([truth["points"][p] for p in blk.points.ids])
    eo = np.array([[truth["photos"][p][k] for k in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
                   for p in blk.photos.ids])
    seen = np.zeros((len(blk.photos), len(blk.points)), bool)
    seen[blk.image.photo, blk.image.point] = True
    k = 1000.0 / plan.image_scale  # mm per m
    n_pts = len(blk.points)
    pc_ids = [f"PC{p}" for p in blk.photos.ids]
    models, strips, om, op, ox, params = [], [], [], [], [], []
    for s in range(plan.strips):
        for j in range(plan.models_per_strip):
            a = s * (plan.models_per_strip + 1) + j
            both = np.flatnonzero(seen[a] & seen[a + 1])
            r = rotation_matrix(rng.normal(0, plan.tilt_rad), rng.normal(0, plan.tilt_rad),
                                rng.normal(0, plan.kappa_rad))
            x0 = eo[a, :3]
            mi = len(models)
            models.append(f"{s + 1}.{j + 1:02d}")
            strips.append(str(s + 1))
            ids = list(both)
            xyz = pts_true[both]
            if plan.projection_centres:
                ids += [n_pts + a, n_pts + a + 1]
                xyz = np.vstack([xyz, eo[[a, a + 1], :3]])
            x = k * (xyz - x0) @ r  # R^T (X - X0) row-wise
            om += [mi] * len(ids)
            op += ids
            ox.append(x)
            params.append((x0, r))
    om, op, ox = np.asarray(om), np.asarray(op), np.vstack(ox)
    ids = list(blk.points.ids) + pc_ids
    pc = np.concatenate([np.zeros(n_pts, bool), np.ones(len(pc_ids), bool)])
    xyz_all = np.vstack([pts_true, eo[:, :3]])
    used = np.bincount(op, minlength=len(ids)) > 0
    remap = np.cumsum(used) - 1
    ids = [p for p, u in zip(ids, used, strict=True) if u]
    pc, xyz_all, op = pc[used], xyz_all[used], remap[op]
    sig_c = _control_layout(xyz_all, pc, plan)
    role = np.where(np.isfinite(sig_c).any(axis=1), "control", "tie").astype(object)
    sig_mm = np.array([plan.sigma_model_um[0]] * 2 + [plan.sigma_model_um[1]]) * 1e-3
    obs_sigma = np.tile(sig_mm, (len(om), 1))
    settings = ModelSettings(name=plan.name, sigma_model_um=tuple(plan.sigma_model_um),
                             sigma_control_m=tuple(plan.sigma_control_m))
    given = np.where((role != "tie")[:, None], xyz_all, np.nan)
    block = ModelBlock(settings, models, np.asarray(strips, dtype=object), ids, role, pc,
                       given.copy(), sig_c, om, op, ox.copy(), obs_sigma, source="simulate")
    true_obs = ox.copy()
    if plan.noise:
        ox = ox + rng.normal(0, 1, ox.shape) * obs_sigma
        given = given + rng.normal(0, 1, given.shape) * np.nan_to_num(sig_c)
    for name, size_um in plan.deformations.items():
        ox = ox + deformation_rows(block, name) * size_um * 1e-3
    log = []
    for _ in range(plan.blunders):
        mult = rng.uniform(*plan.blunder_sigma) * rng.choice([-1.0, 1.0])
        i, c = int(rng.integers(len(om))), int(rng.integers(3))
        ox[i, c] += mult * obs_sigma[i, c]
        log.append({"kind": "model", "model": models[om[i]], "point": ids[op[i]],
                    "component": "xyz"[c], "size_um": mult * obs_sigma[i, c] * 1e3,
                    "sigmas": abs(mult)})
    block.obs_xyz = ox
    block.xyz = given
    truth = {
        "plan": {kk: (list(v) if isinstance(v, tuple) else v) for kk, v in asdict(plan).items()},
        "points": {p: list(x) for p, x in zip(ids, xyz_all.tolist(), strict=True)},
        "models": {m: {"X0": list(map(float, x0)), "R": r.tolist()}
                   for m, (x0, r) in zip(models, params, strict=True)},
        "model_coordinates": true_obs.tolist(),
        "blunders": log,
        "units": {"terrain": "m", "model": "mm"},
    }
    return block, truth


def _control_layout(xyz: np.ndarray, pc: np.ndarray, plan: ModelPlan) -> np.ndarray:
    """Standard deviations (np, 3) of the control: FOTEF's standard single-coverage layout.

    Planimetric control on the borders (every `control_spacing` columns of points on the
    long sides, every point on the short sides), strings of height points crossing the
    strips every `height_chains` columns and at both ends.  NaN = not observed.
    """
    sig = np.full((len(xyz), 3), np.nan)
    g = ~pc
    cols = np.unique(np.round(xyz[g, 0], 3))
    rows = np.unique(np.round(xyz[g, 1], 3))
    ci = np.searchsorted(cols, np.round(xyz[:, 0], 3))
    ri = np.searchsorted(rows, np.round(xyz[:, 1], 3))
    last_c, last_r = len(cols) - 1, len(rows) - 1
    ends = (ci == 0) | (ci == last_c)
    long_side = (ri == 0) | (ri == last_r)
    plan_pts = g & ((long_side & ((ci % max(plan.control_spacing, 1) == 0)
                                                   | (ci == last_c))))
    height = g & (plan.height_chains > 0) & (ends | (ci % max(plan.height_chains, 1) == 0))
    sxy, sz = plan.sigma_control_m[:2], plan.sigma_control_m[2]
    sig[plan_pts, 0], sig[plan_pts, 1] = sxy
    sig[height, 2] = sz
    if plan.full_control:
        sig[plan_pts, 2] = sz
    return sig
