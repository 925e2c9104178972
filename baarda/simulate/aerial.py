"""Synthetic aerial blocks with known truth.

A regular block of `strips` x `photos_per_strip` vertical photos; ground points on a grid
such that every photo measures an n x n pattern (Gruen 1980: 3x3 or 5x5); optional stereo
mode (twin rays), control layouts (perimeter, corners, none; height chains: see FlightPlan),
terrain relief, image noise and injected blunders.  Deterministic for a given seed.  The
photos' positions, the ground points and the control layout come from `ground.py`, GNSS and
IMU observations from `gnss_imu.py`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from baarda.block.camera_models import get_model, invert
from baarda.block.field_models import ebner_fields
from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.bundle.collinearity import project
from baarda.errors import GeometryError
from baarda.kinds import GNSS
from baarda.simulate.gnss_imu import with_gnss_imu
from baarda.simulate.ground import block_geometry


@dataclass
class FlightPlan:
    """Parameters of a simulated block (lengths in m unless stated).

    Control layouts (`control`), on the nodes of the point grid that are measured (seen by
    two photos; the grid's corner nodes are seen by one photo only and never are):

    - ``perimeter``: full (XYZ) control on the first and last rows and columns of the grid,
      every `control_spacing` = k base lengths counted from the edge of the photos' pattern
      windows (the grid corner; with an even pattern the grid line half a node spacing
      outside it), so the first point along a side lies k bases from that edge ((k - 1)
      bases from the corner photo's nadir at 60 % forward overlap); a target where no node is
      measured is skipped.  A corner photo that measures none of these points (a short
      block, 50 % forward overlap, a spacing longer than the block) gets the measured node
      nearest its corner of the grid.  Across the strips the first and last columns are
      measured only where two strips overlap: with a side overlap below 55 % that is one row
      per strip overlap, and the short sides get control only where a target falls on such a
      row (more sparsely than every k bases).
    - ``corners``: full control at the measured node nearest each of the four grid corners.
    - ``none``: no full control.

    Height chains (`height_chains` = h > 0, with any layout): height (Z-only) control on every
    measured node of a grid column across all strips, every h bases counted as the perimeter
    control; nodes that are full control stay full control.  `twin_control` gives every
    control point a companion 0.1 node spacings away.
    """

    strips: int = 3
    photos_per_strip: int = 5
    forward_overlap: float = 0.60
    side_overlap: float = 0.30
    image_scale: float = 10_000.0  # 1 : image_scale
    focal_mm: float = 153.0
    format_mm: float = 230.0
    pattern: int = 3  # n x n image points per photo
    stereo: bool = False  # points of adjacent models measured twice (twin rays)
    neat_area: bool = False  # only points between the outer nadir lines (Gruen's blocks)
    control: str = "perimeter"  # perimeter | corners | none (see above)
    control_spacing: int = 2  # perimeter control every k base lengths
    height_chains: int = 4  # a chain of height points across the strips every k bases; 0: none
    twin_control: bool = False  # each control point with a close companion
    check_points: int = 0  # interior tie points turned into check points
    relief_m: float = 0.0  # amplitude of smooth terrain relief
    sigma_image_um: float = 5.0
    sigma_control_m: tuple[float, float, float] = (0.05, 0.05, 0.10)
    noise: bool = True  # add noise to image and control observations
    eo_error: tuple[float, float] = (1.0, 0.005)  # error of approximate EO: m, rad
    alternate: bool = False  # fly alternate strips in opposite direction
    blunders: int = 0  # number of blunders injected
    blunder_sigma: tuple[float, float] = (6.0, 20.0)  # size range in a-priori sigmas
    blunder_kinds: tuple[str, ...] = ("x", "y")  # x, y (image) and/or X, Y, Z (control)
    # a systematic image deformation, the same on every photo: Ebner's fields (numbers 1..12)
    # on the grid spacing b = format / 2.5, each with the same RMS over the 3 x 3 grid, their
    # sum scaled to this RMS (µm); the observations carry it as a backward model's
    # distortion would.  The default fields b3, b4 (quadratic) bend a block.
    image_deformation_um: float = 0.0
    deformation_fields: tuple[int, ...] = (3, 4)
    # GNSS/IMU (0: none): antenna positions with noise gnss_sigma_m, a shift per strip
    # (each component normal with gnss_offset_m) and a drift per strip (m/km along the
    # strip from its middle, normal with gnss_drift_m_per_km); IMU attitudes, noise in deg
    gnss_sigma_m: float = 0.0
    gnss_offset_m: float = 0.0
    gnss_drift_m_per_km: float = 0.0
    imu_sigma_deg: float = 0.0
    seed: int = 0
    name: str = "simulated"
    extra: dict = field(default_factory=dict)


def deformation_coefficients(plan: FlightPlan) -> tuple[np.ndarray, float]:
    """(Ebner coefficients (12,), grid spacing b [mm]) of the plan's image deformation: each
    of the chosen Ebner fields with the same RMS over the 3 x 3 grid, the sum scaled to
    `image_deformation_um` RMS."""
    b = plan.format_mm / 2.5
    grid = np.array([(x, y) for x in (-b, 0.0, b) for y in (-b, 0.0, b)])
    fields, _ = ebner_fields(grid, np.full(len(grid), b))
    each = np.sqrt(np.mean(np.sum(fields**2, axis=1), axis=0))  # RMS of each field
    chosen = np.zeros(12, bool)
    chosen[[k - 1 for k in plan.deformation_fields]] = True
    coef = np.where(chosen, 1.0 / each, 0.0)
    shift = fields @ coef
    rms = float(np.sqrt(np.mean(np.sum(shift**2, axis=1))))
    return coef * plan.image_deformation_um * 1e-3 / rms, b


def deformed(xy: np.ndarray, plan: FlightPlan) -> np.ndarray:
    """The observations of ideal image coordinates xy (mm, principal point 0) under the
    plan's deformation: u with u + delta(u) = xy for Ebner's backward model."""
    coef, b = deformation_coefficients(plan)
    return invert(get_model("ebner"), xy, coef[None, :], np.array([[b]]))


def simulate_block(plan: FlightPlan) -> tuple[Block, dict]:
    """Simulate a block; returns (block with approximations and noisy observations, truth)."""
    rng = np.random.default_rng(plan.seed)
    g = block_geometry(plan)
    X0, Y0, s_idx, p_idx, seen = g.X0, g.Y0, g.s_idx, g.p_idx, g.seen
    ids, xyz, role, sigma, on_border = g.ids, g.xyz, g.role, g.sigma, g.on_border

    # photos (true exterior orientation)
    kappa = np.where(plan.alternate & (s_idx % 2 == 1), np.pi, 0.0)
    n_ph = len(X0)
    eo_true = np.column_stack([X0, Y0, np.zeros(n_ph), rng.normal(0, 0.01, n_ph),
                               rng.normal(0, 0.01, n_ph), kappa + rng.normal(0, 0.01, n_ph)])
    eo_true[:, 2] = g.flying_height

    notes = []
    if plan.check_points > 0:
        interior = np.flatnonzero((role == "tie") & ~np.concatenate(
            [on_border, np.zeros(len(ids) - len(on_border), bool)]))
        pick = rng.choice(interior, size=min(plan.check_points, len(interior)), replace=False)
        role[pick] = "check"
        if len(pick) < plan.check_points:
            notes.append(f"{plan.check_points} check points asked for, but the block has "
                         f"only {len(pick)} interior tie points: {len(pick)} check points")

    # which photo measures which point
    ph = np.repeat(np.arange(n_ph), [len(ix) for ix in seen])
    pt = np.concatenate(seen)
    rays = np.bincount(pt, minlength=len(ids))
    ok = rays[pt] >= 2
    ph, pt = ph[ok], pt[ok]
    model = None
    if plan.stereo:  # each point measured in every stereo model of its strip: twin rays
        rows_ph, rows_pt, rows_model = [], [], []
        for st in range(plan.strips):
            for j in range(plan.photos_per_strip - 1):
                a = st * plan.photos_per_strip + j
                both = np.intersect1d(seen[a], seen[a + 1])
                both = both[rays[both] >= 2]
                for photo in (a, a + 1):
                    rows_ph.append(np.full(len(both), photo))
                    rows_pt.append(both)
                    rows_model.append(np.full(len(both), f"{st + 1}-{j + 1}", dtype=object))
        ph, pt = np.concatenate(rows_ph), np.concatenate(rows_pt)
        model = np.concatenate(rows_model)
        ok = np.bincount(pt, minlength=len(ids))[pt] >= 2
        ph, pt, model = ph[ok], pt[ok], model[ok]
    order = np.lexsort((pt, ph)) if model is None else np.lexsort((model, pt, ph))
    ph, pt = ph[order], pt[order]
    if model is not None:
        model = model[order]

    if not len(ph):
        raise GeometryError(f"no point of the block is measured on two photos "
                            f"({plan.forward_overlap:.0%} forward and {plan.side_overlap:.0%} "
                            "side overlap): raise the overlaps")
    # drop points that are not measured at all (and renumber)
    used = np.zeros(len(ids), bool)
    used[pt] = True
    remap = np.cumsum(used) - 1
    ids = [p for p, u in zip(ids, used, strict=True) if u]
    xyz, sigma, role = xyz[used], sigma[used], role[used]
    pt = remap[pt]

    focal = np.full(len(ph), plan.focal_mm)
    pp = np.zeros((len(ph), 2))
    xy_true = project(eo_true[ph], xyz[pt], focal, pp)
    if plan.image_deformation_um:
        xy_true = deformed(xy_true, plan)
    sig_mm = plan.sigma_image_um * 1e-3
    xy = xy_true + (rng.normal(0, sig_mm, xy_true.shape) if plan.noise else 0.0)
    ctrl_given = xyz.copy()
    if plan.noise:
        noise = rng.normal(0, 1, xyz.shape) * np.nan_to_num(sigma)
        ctrl_given = xyz + noise
    ctrl_given[role == "tie"] = np.nan

    # blunders
    log = []
    unknown = sorted(set(plan.blunder_kinds) - set("xyXYZ"))
    if unknown:
        raise ValueError(f"blunder kinds: {', '.join(unknown)} unknown (x, y, X, Y, Z)")
    kinds_img = [k for k in plan.blunder_kinds if k in ("x", "y")]
    kinds_ctl = [k for k in plan.blunder_kinds if k in ("X", "Y", "Z")]
    room = {k: len(ph) for k in kinds_img}  # observations of each kind without a blunder
    room.update({k: int(np.sum(np.isfinite(sigma[:, "XYZ".index(k)]) & (role == "control")))
                 for k in kinds_ctl})
    if plan.blunders > sum(room.values()):
        raise ValueError(f"{plan.blunders} blunders asked for, but the block has "
                         f"{sum(room.values())} observations of the kinds "
                         f"{', '.join(plan.blunder_kinds) or '(none)'} (at most one blunder "
                         "in each)")
    used_obs: set[tuple[int | np.integer, str]] = set()
    for _ in range(plan.blunders):
        kind = rng.choice(kinds_img + kinds_ctl)
        if room[kind] == 0:  # every observation of this kind has one: the next kind
            kind = next(k for k in kinds_img + kinds_ctl if room[k] > 0)
        room[kind] -= 1
        mult = rng.uniform(*plan.blunder_sigma) * rng.choice([-1.0, 1.0])
        if kind in ("x", "y"):
            for _try in range(100):
                i = int(rng.integers(len(ph)))
                if (i, kind) not in used_obs:
                    break
            else:  # a crowded block: the first observation without one
                i = next(j for j in range(len(ph)) if (j, kind) not in used_obs)
            used_obs.add((i, kind))
            size = mult * sig_mm
            xy[i, "xy".index(kind)] += size
            log.append({"kind": "image", "photo": f"{_photo_id(s_idx, p_idx, ph[i])}",
                        "point": ids[pt[i]], "component": str(kind), "size": size * 1e3,
                        "unit": "um", "sigmas": abs(mult),
                        "model": None if model is None else str(model[i])})
        else:
            k = "XYZ".index(kind)
            cand = np.flatnonzero(np.isfinite(sigma[:, k]) & (role == "control"))
            cand = [j for j in cand if (j, kind) not in used_obs]
            if not cand:
                continue
            j = int(rng.choice(cand))
            used_obs.add((j, kind))
            size = mult * sigma[j, k]
            ctrl_given[j, k] += size
            log.append({"kind": "control", "photo": None, "point": ids[j],
                        "component": str(kind), "size": size, "unit": "m",
                        "sigmas": abs(mult)})

    eo_approx = eo_true.copy()
    eo_approx[:, :3] += rng.normal(0, plan.eo_error[0], (n_ph, 3))
    eo_approx[:, 3:] += rng.normal(0, plan.eo_error[1], (n_ph, 3))
    xyz_given = np.where((role == "tie")[:, None], np.nan, ctrl_given)
    photo_ids = [_photo_id(s_idx, p_idx, i) for i in range(n_ph)]
    settings = Settings(name=plan.name, angle_unit="gon", sigma_image_um=plan.sigma_image_um,
                        sigma_control_m=tuple(plan.sigma_control_m))  # type: ignore[arg-type]  # the plan's 3
    block = Block(
        settings,
        Cameras(["cam"], np.array([plan.focal_mm]), np.zeros((1, 2))),
        Photos(photo_ids, np.zeros(n_ph, dtype=np.int64),
               np.array([f"{s + 1}" for s in s_idx], dtype=object), eo_approx),
        ImagePoints(ph.astype(np.int64), pt.astype(np.int64), xy, np.full(len(ph), sig_mm),
                    model),
        GroundPoints(ids, xyz_given, sigma, role),
        source="simulate",
        notes=notes,
    )
    truth = {
        "plan": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(plan).items()},
        "photos": {pid: {"X0": e[0], "Y0": e[1], "Z0": e[2], "omega": e[3], "phi": e[4],
                         "kappa": e[5]} for pid, e in zip(photo_ids, eo_true.tolist(),
                                                           strict=True)},
        "points": {pid: list(p) for pid, p in zip(ids, xyz.tolist(), strict=True)},
        "blunders": log,
        "units": {"angles": "rad", "coordinates": "m"},
    }
    if plan.gnss_sigma_m > 0 or plan.imu_sigma_deg > 0:
        block, truth[GNSS.name] = with_gnss_imu(plan, block, eo_true)
    if plan.image_deformation_um:
        coef, b = deformation_coefficients(plan)
        truth["camera"] = {"model": "ebner", "b": b, "coefficients": coef.tolist()}
    return block, truth


def _photo_id(s_idx: np.ndarray, p_idx: np.ndarray, i: int) -> str:
    return f"{s_idx[i] + 1:02d}{p_idx[i] + 1:03d}"
