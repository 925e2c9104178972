"""Synthetic aerial blocks with known truth.

A regular block of `strips` x `photos_per_strip` vertical photos; ground points on a grid
such that every photo measures an n x n pattern (Gruen 1980: 3x3 or 5x5); optional stereo
mode (twin rays), control layouts (perimeter, corners, none; height chains: see FlightPlan),
terrain relief, image noise and injected blunders.  Deterministic for a given seed.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from baarda.block.camera_models import get_model, invert
from baarda.block.field_models import ebner_fields
from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.bundle.collinearity import project


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


def _terrain(x: np.ndarray, y: np.ndarray, amplitude: float, size: float) -> np.ndarray:
    if amplitude == 0:
        return np.zeros_like(x)
    k = 2 * np.pi / max(size, 1.0)
    return amplitude * (0.5 * np.sin(1.3 * k * x + 0.4) * np.cos(0.9 * k * y)
                        + 0.3 * np.sin(2.1 * k * y + 1.1) + 0.2 * np.cos(2.7 * k * (x + y)))

@dataclass(frozen=True)
class GroundLayout:
    """The ground points of a simulated block: ids, true coordinates (n, 3), roles (tie |
    control) and a-priori sigmas of the control coordinates (n, 3; NaN: not given)."""

    ids: list[str]
    xyz: np.ndarray
    role: np.ndarray
    sigma: np.ndarray


def ground_layout(plan: FlightPlan) -> GroundLayout:
    """The points simulate_block(plan) measures, with the control layout of the plan: no
    photos, observations, noise, check points or blunders (the layout of a large block in a
    fraction of the time)."""
    g = _ground(plan)
    kept = np.flatnonzero(_kept(g.seen, plan, len(g.ids)))
    return GroundLayout([g.ids[j] for j in kept], g.xyz[kept], g.role[kept], g.sigma[kept])


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
    g = _ground(plan)
    X0, Y0, s_idx, p_idx, seen = g.X0, g.Y0, g.s_idx, g.p_idx, g.seen
    ids, xyz, role, sigma, on_border = g.ids, g.xyz, g.role, g.sigma, g.on_border

    # photos (true exterior orientation)
    kappa = np.where(plan.alternate & (s_idx % 2 == 1), np.pi, 0.0)
    n_ph = len(X0)
    eo_true = np.column_stack([X0, Y0, np.zeros(n_ph), rng.normal(0, 0.01, n_ph),
                               rng.normal(0, 0.01, n_ph), kappa + rng.normal(0, 0.01, n_ph)])
    eo_true[:, 2] = g.flying_height

    if plan.check_points > 0:
        interior = np.flatnonzero((role == "tie") & ~np.concatenate(
            [on_border, np.zeros(len(ids) - len(on_border), bool)]))
        pick = rng.choice(interior, size=min(plan.check_points, len(interior)), replace=False)
        role[pick] = "check"

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
    kinds_img = [k for k in plan.blunder_kinds if k in ("x", "y")]
    kinds_ctl = [k for k in plan.blunder_kinds if k in ("X", "Y", "Z")]
    used_obs = set()
    for _ in range(plan.blunders):
        kind = rng.choice(kinds_img + kinds_ctl)
        mult = rng.uniform(*plan.blunder_sigma) * rng.choice([-1.0, 1.0])
        if kind in ("x", "y"):
            for _try in range(100):
                i = int(rng.integers(len(ph)))
                if (i, kind) not in used_obs:
                    break
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
                        sigma_control_m=tuple(plan.sigma_control_m))
    block = Block(
        settings,
        Cameras(["cam"], np.array([plan.focal_mm]), np.zeros((1, 2))),
        Photos(photo_ids, np.zeros(n_ph, dtype=np.int64),
               np.array([f"{s + 1}" for s in s_idx], dtype=object), eo_approx),
        ImagePoints(ph.astype(np.int64), pt.astype(np.int64), xy, np.full(len(ph), sig_mm),
                    model),
        GroundPoints(ids, xyz_given, sigma, role),
        source="simulate",
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
        block, truth["gnss"] = _gnss_imu(plan, block, eo_true)
    if plan.image_deformation_um:
        coef, b = deformation_coefficients(plan)
        truth["camera"] = {"model": "ebner", "b": b, "coefficients": coef.tolist()}
    return block, truth


@dataclass(frozen=True)
class _Ground:
    """The photo positions and the ground points of a plan, each point with the photos that
    see it (before dropping those seen by fewer than two)."""

    X0: np.ndarray
    Y0: np.ndarray
    s_idx: np.ndarray  # strip of each photo
    p_idx: np.ndarray  # photo in its strip
    flying_height: float  # Z0 of the photos
    ids: list[str]
    xyz: np.ndarray
    role: np.ndarray
    sigma: np.ndarray
    on_border: np.ndarray  # the first and last rows and columns (grid points only)
    seen: list[np.ndarray]  # the points inside the pattern window of each photo


def _ground(plan: FlightPlan) -> _Ground:
    """The photos' positions, the grid of ground points and the control layout."""
    n = plan.pattern
    if n < 2:
        raise ValueError("pattern must be at least 2 (2x2 points per photo)")
    side = plan.format_mm * 1e-3 * plan.image_scale  # ground side of a photo
    base = (1 - plan.forward_overlap) * side
    dist = (1 - plan.side_overlap) * side
    height = plan.focal_mm * 1e-3 * plan.image_scale
    ex = base if base <= 0.45 * side else base / 2
    ey = dist if dist <= 0.45 * side else dist / 2
    dx, dy = 2 * ex / (n - 1), 2 * ey / (n - 1)

    # photo positions
    s_idx, p_idx = np.meshgrid(np.arange(plan.strips), np.arange(plan.photos_per_strip),
                               indexing="ij")
    s_idx, p_idx = s_idx.ravel(), p_idx.ravel()
    X0 = p_idx * base
    Y0 = s_idx * dist

    # ground grid covering every pattern window
    gx = np.arange(np.floor(-ex / dx), np.ceil((X0.max() + ex) / dx) + 1) * dx
    gy = np.arange(np.floor(-ey / dy), np.ceil((Y0.max() + ey) / dy) + 1) * dy
    GX, GY = np.meshgrid(gx, gy, indexing="xy")
    gxy = np.column_stack([GX.ravel(), GY.ravel()])
    cols = np.rint(gxy[:, 0] / dx).astype(int)
    rows = np.rint(gxy[:, 1] / dy).astype(int)
    if plan.neat_area:
        inside = ((gxy[:, 0] > -1e-6) & (gxy[:, 0] < X0.max() + 1e-6) &
                  (gxy[:, 1] > -1e-6) & (gxy[:, 1] < Y0.max() + 1e-6))
        gxy, cols, rows = gxy[inside], cols[inside], rows[inside]
    ids = [f"{r:03d}{c:03d}" for r, c in zip((rows - rows.min() + 1).tolist(),
                                             (cols - cols.min() + 1).tolist(), strict=True)]
    size = max(X0.max(), Y0.max(), side)
    Z = _terrain(gxy[:, 0], gxy[:, 1], plan.relief_m, size)
    xyz = np.column_stack([gxy, Z])
    role = np.full(len(ids), "tie", dtype=object)
    sigma = np.full((len(ids), 3), np.nan)

    # control layout on the grid.  The outermost rows and columns of the grid can lie outside
    # every pattern window (always with an even pattern, whose nodes straddle the window
    # edges; with an odd one where floor and ceil round a ratio such as -7.000000000000001 to
    # -8): they are never measured and are dropped below, and control placed on them would be
    # lost with them.  So the borders are the outermost nodes inside the windows, and the
    # control is counted in steps of bases from the grid line at the window edge (odd
    # pattern: the border itself; even pattern: half a node spacing outside it)
    window = (ex + 0.2 * dx, ey + 0.2 * dy)  # half sides of the area a photo measures
    tol = 1e-6 * min(dx, dy)
    in_windows = ((xyz[:, 0] >= -ex - tol) & (xyz[:, 0] <= X0.max() + ex + tol) &
                  (xyz[:, 1] >= -ey - tol) & (xyz[:, 1] <= Y0.max() + ey + tol))
    ext = (xyz[in_windows, 0].min(), xyz[in_windows, 0].max(),
           xyz[in_windows, 1].min(), xyz[in_windows, 1].max())
    x0 = xyz[xyz[:, 0] >= -ex - dx / 2 - tol, 0].min()
    y0 = xyz[xyz[:, 1] >= -ey - dy / 2 - tol, 1].min()
    on_border = (np.isclose(xyz[:, 0], ext[0]) | np.isclose(xyz[:, 0], ext[1]) |
                  np.isclose(xyz[:, 1], ext[2]) | np.isclose(xyz[:, 1], ext[3]))
    seen = _seen(xyz, X0, Y0, window)  # which photo measures which node
    measured = _kept(seen, plan, len(ids))  # the nodes kept below
    kept = np.flatnonzero(measured)
    # the corner photos (first and last of the first and last strip) and their grid corners
    last, n_ph = plan.photos_per_strip - 1, len(X0)
    corners = [(0, ext[0], ext[2]), (last, ext[1], ext[2]),
               (n_ph - 1 - last, ext[0], ext[3]), (n_ph - 1, ext[1], ext[3])]
    full = np.zeros(len(ids), bool)
    if plan.control == "perimeter":
        step = plan.control_spacing * base
        kx = np.rint((xyz[:, 0] - x0) / step)
        ky = np.rint((xyz[:, 1] - y0) / step)
        on_x = np.isclose(xyz[:, 0] - x0, kx * step, atol=dx / 2 + 1e-6)
        on_y = np.isclose(xyz[:, 1] - y0, ky * step, atol=dy / 2 + 1e-6)
        # a node every step along the first and last rows and columns
        full = on_border & ((on_x & np.isin(np.rint(xyz[:, 1]), np.rint([ext[2], ext[3]]))) |
                            (on_y & np.isin(np.rint(xyz[:, 0]), np.rint([ext[0], ext[1]]))))
        # a corner photo that measures none of these (a block of few photos, 50 % forward
        # overlap, a spacing longer than the block) gets the measured node nearest its corner
        controlled = full & measured
        for photo, cx, cy in corners if kept.size else ():
            if not controlled[seen[photo]].any():
                full[_nearest(xyz, kept, cx, cy)] = True
    elif plan.control == "corners":
        # the measured node nearest each corner (the corner node is seen by one photo only)
        for _photo, cx, cy in corners if kept.size else ():
            full[_nearest(xyz, kept, cx, cy)] = True
    elif plan.control != "none":
        raise ValueError(f"unknown control layout '{plan.control}'")
    role[full] = "control"
    sigma[full] = plan.sigma_control_m
    if plan.height_chains > 0:  # a column of height points, those not full control already
        step = plan.height_chains * base
        k = np.rint((xyz[:, 0] - x0) / step)
        chain = np.isclose(xyz[:, 0] - x0, k * step, atol=dx / 2 + 1e-6) & ~full
        role[chain] = "control"
        sigma[chain, 2] = plan.sigma_control_m[2]

    if plan.twin_control:
        ctrl = np.flatnonzero(role == "control")
        offset = np.array([0.1 * dx, 0.1 * dy, 0.0])
        twin_xyz = xyz[ctrl] + offset
        twin_xyz[:, 2] = _terrain(twin_xyz[:, 0], twin_xyz[:, 1], plan.relief_m, size)
        xyz = np.vstack([xyz, twin_xyz])
        ids += [ids[j] + "T" for j in ctrl]
        role = np.concatenate([role, role[ctrl]])
        sigma = np.vstack([sigma, sigma[ctrl]])
        seen = _seen(xyz, X0, Y0, window)  # with the twins
    return _Ground(X0, Y0, s_idx, p_idx, height + np.mean(Z), ids, xyz, role, sigma,
                   on_border, seen)


def _seen(xyz: np.ndarray, X0: np.ndarray, Y0: np.ndarray,
          window: tuple[float, float]) -> list[np.ndarray]:
    """The points (sorted indices) inside the pattern window around each photo's nadir: a k-d
    tree in coordinates scaled by the window, Chebyshev distance <= 1 (no photos x points
    matrix)."""
    wx, wy = window
    tree = cKDTree(np.column_stack([xyz[:, 0] / wx, xyz[:, 1] / wy]))
    return [np.sort(np.asarray(ix, dtype=np.int64)) for ix in
            tree.query_ball_point(np.column_stack([X0 / wx, Y0 / wy]), r=1.0, p=np.inf)]


def _kept(seen: list[np.ndarray], plan: FlightPlan, n_points: int) -> np.ndarray:
    """The points simulate_block keeps: seen by two photos (stereo: by both photos of a
    model)."""
    if not plan.stereo:
        return np.bincount(np.concatenate(seen), minlength=n_points) >= 2
    kept = np.zeros(n_points, bool)
    for st in range(plan.strips):
        for j in range(plan.photos_per_strip - 1):
            a = st * plan.photos_per_strip + j
            kept[np.intersect1d(seen[a], seen[a + 1])] = True
    return kept


def _nearest(xyz: np.ndarray, candidates: np.ndarray, x: float, y: float) -> int:
    """The candidate point nearest (x, y) in plan (the first of equals)."""
    return int(candidates[np.argmin(np.hypot(xyz[candidates, 0] - x, xyz[candidates, 1] - y))])


def _photo_id(s_idx: np.ndarray, p_idx: np.ndarray, i: int) -> str:
    return f"{s_idx[i] + 1:02d}{p_idx[i] + 1:03d}"


def _gnss_imu(plan: FlightPlan, block: Block, eo_true: np.ndarray) -> tuple[Block, dict]:
    """GNSS antenna positions (lever arm 0) and IMU attitudes of every photo, with their
    errors drawn from a random stream of their own (the rest of the block is as without)."""
    from dataclasses import replace

    from baarda.block.photo_block import GnssObservations, ImuObservations

    rng = np.random.default_rng([plan.seed, 14])
    n = len(eo_true)
    strips = np.asarray(block.photos.strip, dtype=object)
    labels = sorted(set(strips.tolist()), key=int)
    truth: dict = {"shift": {}, "drift_m_per_km": {}}
    settings = block.settings
    if plan.gnss_sigma_m > 0:
        pos = eo_true[:, :3].copy()
        for lab in labels:
            sel = strips == lab
            shift = rng.normal(0.0, plan.gnss_offset_m, 3) if plan.gnss_offset_m else np.zeros(3)
            drift = (rng.normal(0.0, plan.gnss_drift_m_per_km, 3) if plan.gnss_drift_m_per_km
                     else np.zeros(3))
            xy = eo_true[sel, :2]
            d = xy - xy.mean(axis=0)
            u = np.linalg.svd(d, full_matrices=False)[2][0] if len(d) > 1 else np.array([1, 0])
            pos[sel] += shift + np.outer(d @ u / 1000.0, drift)
            truth["shift"][lab] = shift.tolist()
            truth["drift_m_per_km"][lab] = drift.tolist()
        pos += rng.normal(0.0, plan.gnss_sigma_m, (n, 3))
        block = replace(block, gnss=GnssObservations(np.arange(n), pos,
                                                     np.full((n, 3), plan.gnss_sigma_m)))
        settings = replace(settings, gnss_offsets="strip" if plan.gnss_offset_m else "none",
                           gnss_drift=bool(plan.gnss_drift_m_per_km))
    if plan.imu_sigma_deg > 0:
        s = np.radians(plan.imu_sigma_deg)
        ang = eo_true[:, 3:] + rng.normal(0.0, s, (n, 3))
        block = replace(block, imu=ImuObservations(np.arange(n), ang, np.full((n, 3), s)))
    return replace(block, settings=settings), truth
