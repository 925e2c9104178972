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

from baarda.block.model_block import ModelBlock, ModelSettings
from baarda.block.rotation import rotation_matrix
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
    layout: str = "grid"  # grid (6 points per model) | fotef (8: two per corner)
    single_end_points: bool = False  # fotef: one point at the block corners
    seed: int = 0
    name: str = "simulated models"


def _grid_layout(plan: ModelPlan):
    """Points of baarda.simulate.aerial (3 x 3 per photo): 6 per model (von Gruber)."""
    fp = FlightPlan(strips=plan.strips, photos_per_strip=plan.models_per_strip + 1,
                    forward_overlap=plan.forward_overlap, side_overlap=plan.side_overlap,
                    image_scale=plan.image_scale, focal_mm=plan.focal_mm,
                    format_mm=plan.format_mm, pattern=3, control="none", height_chains=0,
                    relief_m=plan.relief_m, noise=False, seed=plan.seed)
    blk, truth = simulate_block(fp)
    pts = np.array([truth["points"][p] for p in blk.points.ids])
    pcs = np.array([[truth["photos"][p][k] for k in ("X0", "Y0", "Z0")]
                    for p in blk.photos.ids])
    seen = np.zeros((len(blk.photos), len(blk.points)), bool)
    seen[blk.image.photo, blk.image.point] = True
    members = []
    for s in range(plan.strips):
        for j in range(plan.models_per_strip):
            a = s * (plan.models_per_strip + 1) + j
            members.append(np.flatnonzero(seen[a] & seen[a + 1]))
    return list(blk.points.ids), pts, list(blk.photos.ids), pcs, members, None


def _fotef_layout(plan: ModelPlan):
    """FOTEF's test blocks (Appendix I): two points at each model corner, 8 per model.

    On the block borders both points of a corner lie in the same models; on a boundary
    between strips one point is common to both strips (4 models) and each strip has its own
    second point (2 models).  Planimetric control on the borders (every `control_spacing`
    bases on the long sides, every corner on the short sides), height strings every
    `height_chains` bases and at the ends; only the first point of a corner is control.
    """
    side = plan.format_mm * 1e-3 * plan.image_scale
    base, dist = (1 - plan.forward_overlap) * side, (1 - plan.side_overlap) * side
    h = plan.focal_mm * 1e-3 * plan.image_scale
    ns, nm = plan.strips, plan.models_per_strip
    dx, dy = 0.1 * base, 0.1 * dist
    ids, xyz, models_of, sig = [], [], [], []
    sc = plan.sigma_control_m

    def add(name, x, y, strips, c, control):
        ids.append(name)
        xyz.append([x, y, 0.0])
        models_of.append([(s, j) for s in strips for j in (c - 1, c) if 0 <= j < nm])
        sg = [np.nan] * 3
        if control[0]:
            sg[0], sg[1] = sc[0], sc[1]
        if control[1]:
            sg[2] = sc[2]
        sig.append(sg if not plan.full_control or not control[0] else [sc[0], sc[1], sc[2]])

    for i in range(ns + 1):
        y = (i - 0.5) * dist
        strips = [s for s in (i - 1, i) if 0 <= s < ns]
        for c in range(nm + 1):
            x = c * base
            border = i in (0, ns)
            ends = c in (0, nm)
            plan_ctrl = (border and (c % max(plan.control_spacing, 1) == 0 or ends)) or ends
            h_ctrl = plan.height_chains > 0 and (ends or c % plan.height_chains == 0)
            add(f"{i + 1}{c + 1:02d}1", x, y, strips, c, (plan_ctrl, h_ctrl))
            if border and ends and plan.single_end_points:
                continue
            if border:
                add(f"{i + 1}{c + 1:02d}2", x + (dx if c < nm else -dx), y, strips, c,
                    (False, False))
            else:
                add(f"{i + 1}{c + 1:02d}2", x, y + dy, [i], c, (False, False))
                add(f"{i + 1}{c + 1:02d}3", x, y - dy, [i - 1], c, (False, False))
    members: list[list[int]] = [[] for _ in range(ns * nm)]
    for p, mods in enumerate(models_of):
        for s, j in mods:
            members[s * nm + j].append(p)
    photo_ids = [f"{s + 1:02d}{c + 1:03d}" for s in range(ns) for c in range(nm + 1)]
    pcs = np.array([[c * base, s * dist, h] for s in range(ns) for c in range(nm + 1)])
    return (ids, np.array(xyz), photo_ids, pcs, [np.array(m) for m in members],
            np.array(sig, float))


def simulate_models(plan: ModelPlan) -> tuple[ModelBlock, dict]:
    """Simulate a model block; returns (block with noisy observations, truth)."""
    from baarda.block.model_deformations import deformation_rows

    rng = np.random.default_rng(plan.seed)
    if plan.layout == "grid":
        names, pts_true, photo_ids, pcs, members, sig_pts = _grid_layout(plan)
    elif plan.layout == "fotef":
        names, pts_true, photo_ids, pcs, members, sig_pts = _fotef_layout(plan)
    else:
        raise ValueError(f"unknown layout '{plan.layout}' (grid or fotef)")
    k = 1000.0 / plan.image_scale  # mm per m
    n_pts = len(names)
    pc_ids = [f"PC{p}" for p in photo_ids]
    models: list[str] = []
    strips, om, op, ox, params = [], [], [], [], []
    for s in range(plan.strips):
        for j in range(plan.models_per_strip):
            a = s * (plan.models_per_strip + 1) + j
            both = members[s * plan.models_per_strip + j]
            r = rotation_matrix(rng.normal(0, plan.tilt_rad), rng.normal(0, plan.tilt_rad),
                                rng.normal(0, plan.kappa_rad))
            x0 = pcs[a]
            mi = len(models)
            models.append(f"{s + 1}.{j + 1:02d}")
            strips.append(str(s + 1))
            ids = list(both)
            xyz = pts_true[both]
            if plan.projection_centres:
                ids += [n_pts + a, n_pts + a + 1]
                xyz = np.vstack([xyz, pcs[[a, a + 1]]])
            x = k * (xyz - x0) @ r  # R^T (X - X0) row-wise
            om += [mi] * len(ids)
            op += ids
            ox.append(x)
            params.append((x0, r))
    om, op, ox = np.asarray(om), np.asarray(op), np.vstack(ox)
    ids = names + pc_ids
    pc = np.concatenate([np.zeros(n_pts, bool), np.ones(len(pc_ids), bool)])
    xyz_all = np.vstack([pts_true, pcs])
    used = np.bincount(op, minlength=len(ids)) > 0
    remap = np.cumsum(used) - 1
    ids = [p for p, u in zip(ids, used, strict=True) if u]
    pc, xyz_all, op = pc[used], xyz_all[used], remap[op]
    if sig_pts is None:
        sig_c = _control_layout(xyz_all, pc, plan)
    else:
        sig_c = np.vstack([sig_pts, np.full((len(pc_ids), 3), np.nan)])[used]
    role = np.where(np.isfinite(sig_c).any(axis=1), "control", "tie").astype(object)
    sig_mm = np.array([plan.sigma_model_um[0]] * 2 + [plan.sigma_model_um[1]]) * 1e-3
    obs_sigma = np.tile(sig_mm, (len(om), 1))
    settings = ModelSettings(name=plan.name, sigma_model_um=tuple(plan.sigma_model_um),  # type: ignore[arg-type]
                             sigma_control_m=tuple(plan.sigma_control_m))  # type: ignore[arg-type]
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
    if plan.blunders > ox.size:
        raise ValueError(f"{plan.blunders} blunders asked for, but the block has {ox.size} "
                         "model coordinates")
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
    every = (ci % max(plan.control_spacing, 1) == 0) | (ci == last_c)
    plan_pts = g & (ends | (long_side & every))
    height = g & (plan.height_chains > 0) & (ends | (ci % max(plan.height_chains, 1) == 0))
    sxy, sz = plan.sigma_control_m[:2], plan.sigma_control_m[2]
    sig[plan_pts, 0], sig[plan_pts, 1] = sxy
    sig[height, 2] = sz
    if plan.full_control:
        sig[plan_pts, 2] = sz
    return sig
