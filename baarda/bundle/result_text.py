"""The bundle result told to people: its summary sections, the camera parameters with their
standard deviations and correlations (BundleResult's text and tables; bundle_result.py holds
the numbers)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from baarda.sections import Section, at_most, section

if TYPE_CHECKING:
    from baarda.block.photo_block import Block
    from baarda.bundle.bundle_result import BundleResult
    from baarda.bundle.calibration import Calibration

HIGH_CORRELATION = 0.95  # camera parameters correlated beyond this are reported
EO_NAMES = ("X0", "Y0", "Z0", "omega", "phi", "kappa")


def sections(res: BundleResult) -> list[Section]:
    d = res.to_dict()
    im = np.where(res.lin.w > 0, res.image_residuals * 1e3, np.nan)
    rows = res.problem.extra_range["border_images"]  # image rows of points tied by distances
    mb = (rows.stop - rows.start) // 2
    if mb:
        assert res.lin.wx is not None and res.lin.ex is not None
        wb = res.lin.wx[rows, 0].reshape(mb, 2)
        im = np.vstack([im, np.where(wb > 0, -res.lin.ex[rows, 0].reshape(mb, 2) * 1e3,
                                     np.nan)])
    lines = [] if res.converged else [
        f"NOT CONVERGED after {res.iterations} iterations: the results are not a "
        "least-squares solution (see the notes)"]
    lines += [
        res.block.summary(),
        res.problem.datum_text(),
        res.problem.apriori_text(),
        res.observations_text(),
        f"iterations {d['iterations']} ({'converged' if d['converged'] else 'NOT converged'}"
        f")" + (f", then {res.refits[0]} re-adjustment(s) by data snooping (the last: "
                f"{res.refits[1]} iteration(s))" if res.refits[0] else "")
        + f", {d['seconds']:.2f} s",
        f"sigma0 a posteriori {d['sigma0']:.4f}",
        f"RMS image residuals x {np.sqrt(np.nanmean(im[:, 0]**2)):.2f} µm, "
        f"y {np.sqrt(np.nanmean(im[:, 1]**2)):.2f} µm (rejected ones left out)",
    ]
    if d["n_check_points"]:
        after = (" after a 7-parameter similarity onto them (free network)"
                 if res.check_similarity() is not None else "")
        lines.append(f"check points {d['n_check_points']}{after}: RMS X "
                     f"{d['check_rms_X']:.3f} m, Y {d['check_rms_Y']:.3f} m, Z "
                     f"{d['check_rms_Z']:.3f} m")
    lines += [f"note: {n}" for n in list(res.block.notes) + list(res.notes)]
    out = [section("Bundle block adjustment", lines)]
    if res.problem.calibration.n:
        out.append(section("Camera calibration", calibration_lines(res)))
    return out

# --------------------------------------------------------- res-calibration
def camera_table(res: BundleResult) -> list[dict]:
    """Every parameter of every camera: its initial (given) value, the adjusted value, the
    standard deviation (None when held), estimated or not (units: mm for c, x0, y0; the
    model's units else)."""
    cal = res.problem.calibration
    params = cal.current(res._g, res.state[0][:, 6:])
    out = []
    for i, cid in enumerate(res.block.cameras.ids):
        std = np.sqrt(np.maximum(np.diag(res.camera_cofactors(i)), 0)) * res.sigma0 \
            if len(cal.free_index[i]) else np.zeros(0)
        free = dict(zip(cal.free_index[i].tolist(), std.tolist(), strict=True))
        for j, name in enumerate(cal.names[i]):
            out.append({"camera": cid, "model": cal.models[i].name, "parameter": name,
                        "initial": float(cal.nominal[i][j]),
                        "value": float(params[i][j]),
                        "sigma": float(free[j]) if j in free else None,
                        "estimated": j in free})
    return out

def camera_correlations(res: BundleResult) -> list[dict]:
    """Per camera with estimated parameters: their names and correlation matrix
    (summary.json 'camera_correlations'; the report's heat map)."""
    cal = res.problem.calibration
    q = res.camera_covariance()
    s = np.sqrt(np.maximum(np.diag(q), 1e-300))
    r = q / np.outer(s, s) if len(q) else q
    out = []
    for i, cid in enumerate(res.block.cameras.ids):
        if not len(cal.free_index[i]):
            continue
        if cal.owner[i] < 0:
            cols = cal.columns[i]
            ri = r[np.ix_(cols, cols)]
        else:
            qi = res.camera_cofactors(i)
            si = np.sqrt(np.maximum(np.diag(qi), 1e-300))
            ri = qi / np.outer(si, si)
        out.append({"camera": cid,
                    "parameters": [cal.names[i][j] for j in cal.free_index[i]],
                    "matrix": np.round(ri, 6).tolist()})
    return out

def high_correlations(res: BundleResult, limit: float = HIGH_CORRELATION) -> list[str]:
    """Pairs of estimated camera parameters, and camera parameters with orientation
    unknowns of a photo, correlated beyond `limit` (by the largest |r|).  A camera in its
    photo's block: with its own parameters and its photo's orientation (the other
    photos' unknowns are not in the selected inverse's blocks of that photo)."""
    cal = res.problem.calibration
    a: int | np.integer  # numpy indices, then range()
    b: int | np.integer
    out = []
    q = res.camera_covariance()
    if len(q):
        s = np.sqrt(np.maximum(np.diag(q), 1e-300))
        r = q / np.outer(s, s)
        labels = cal.global_labels
        for a, b in zip(*np.triu_indices(len(q), 1), strict=True):
            if abs(r[a, b]) > limit:
                out.append((abs(r[a, b]), f"{labels[a]} with {labels[b]} "
                                          f"{r[a, b]:+.3f}"))
        # with the photos' unknowns (orientation, and a camera in the photo's block)
        qf = res._frame_cofactors
        sf = np.sqrt(np.maximum(np.diagonal(qf, axis1=1, axis2=2), 1e-300))
        qfg = res.factor.frame_global_covariance()[:, :, :len(q)]
        rfg = qfg / (sf[:, :, None] * s[None, None, :])
        for g in range(len(q)):
            f, b = np.unravel_index(int(np.argmax(np.abs(rfg[:, :, g]))), rfg.shape[:2])
            if abs(rfg[f, b, g]) > limit:
                out.append((abs(rfg[f, b, g]), f"{labels[g]} with "
                            f"{_photo_unknown(res, f, b)} {rfg[f, b, g]:+.3f}"))
    owned = np.flatnonzero(cal.owner >= 0)
    if len(owned):
        qb = res._frame_cofactors
        sb = np.sqrt(np.maximum(np.diagonal(qb, axis1=1, axis2=2), 1e-300))
        rb = qb / (sb[:, :, None] * sb[:, None, :])
        for i in owned:
            f = cal.owner[i]
            names = [cal.names[i][j] for j in cal.free_index[i]]
            cid = res.block.cameras.ids[i]
            for a in range(len(names)):
                for b in range(a + 1, len(names)):
                    x = rb[f, 6 + a, 6 + b]
                    if abs(x) > limit:
                        out.append((abs(x), f"{names[a]} of camera {cid} with {names[b]} "
                                            f"of camera {cid} {x:+.3f}"))
                b = int(np.argmax(np.abs(rb[f, 6 + a, :6])))
                x = rb[f, 6 + a, b]
                if abs(x) > limit:
                    out.append((abs(x), f"{names[a]} of camera {cid} with "
                                        f"{_photo_unknown(res, f, b)} {x:+.3f}"))
    return [text for _, text in sorted(out, reverse=True)]

def photo_unknown_names(block: Block, cal: Calibration, photo: int) -> list[str]:
    """The names of a photo's unknowns: its orientation ('X0 of photo P'), then the free
    parameters of the camera it owns ('c of camera C'; calibration.py)."""
    names = [f"{n} of photo {block.photos.ids[photo]}" for n in EO_NAMES]
    return names + [f"{cal.names[i][j]} of camera {block.cameras.ids[i]}"
                    for i in np.flatnonzero(cal.owner == photo) for j in cal.free_index[i]]


def _photo_unknown(res: BundleResult, photo: int | np.integer, k: int | np.integer) -> str:
    """The name of unknown k of a photo's block: 'X0 of photo P', 'c of camera C'."""
    return photo_unknown_names(res.block, res.problem.calibration, int(photo))[int(k)]

def calibration_lines(res: BundleResult) -> list[str]:
    """The estimated camera parameters with standard deviations, and the high
    correlations (the significance tests are in the quality section)."""
    lines = []
    by_camera: dict[str, list[dict]] = {}
    for r in camera_table(res):
        by_camera.setdefault(r["camera"], []).append(r)
    cameras = []
    for cid in res.block.cameras.ids:
        rows = by_camera[cid]
        est = [f"{r['parameter']} {r['value']:.6g} +- {r['sigma']:.2g}" for r in rows
               if r["estimated"]]
        held = [f"{r['parameter']} {r['value']:.6g}" for r in rows
                if not r["estimated"] and r["value"] != 0]
        cameras.append(f"camera {cid} ({rows[0]['model']}): " + (", ".join(est) or "held")
                       + (f"; held: {', '.join(held)}" if held else ""))
    lines += at_most(cameras, "camera(s) (every parameter of every camera in cameras.csv)")
    high = high_correlations(res)
    if high:
        lines.append(f"high correlations (|r| > {HIGH_CORRELATION}): " + "; ".join(high[:8])
                     + (f"; and {len(high) - 8} more" if len(high) > 8 else ""))
    return lines
