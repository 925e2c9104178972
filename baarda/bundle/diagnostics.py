"""What makes approximations unusable, found before adjusting and said in words.

A bundle adjustment that starts from wrong approximations fails far from the cause ("the
orientation of photo 7 is not determined", "diverged").  `diagnose(block)` looks at the
inputs the way a photogrammetrist would, before the solver:

* image coordinates far outside any image format (pixels given as mm, a slipped digit):
  a frame camera images a point at most a few camera constants c from the principal
  point; beyond `MAX_FIELD` c it cannot;
* angles that cannot be in the project's angle unit (radians beyond 2 pi);
* coordinates beyond the size of the Earth (units, offsets);
* rays that do not meet: every point is intersected from the approximate orientations
  (control as given) and projected back; the misclosure (mm in the image) per photo shows
  a photo whose orientation is wrong, and trying kappa + 200 gon and the other angle units
  names the likely cause.

Hopeless inputs raise GeometryError; the rest are findings (strings) that the pipeline
keeps on the problem, prints as notes and adds to the message if the adjustment fails.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baarda.block.camera import ideal_image_coordinates
from baarda.block.photo_block import Block, Photos
from baarda.block.rotation import ANGLE_FACTORS
from baarda.bundle.collinearity import project
from baarda.bundle.geometry import intersect, usable_points
from baarda.errors import GeometryError, figure

MAX_FIELD = 10.0  # image radius / c beyond which no frame camera images (84 deg off axis)
PIXELS_FIELD = 3.0  # a median image radius / c beyond this: coordinates are not in mm
EARTH_M = 1e8  # no map or geocentric coordinate is larger (Earth radius 6.4e6 m)
BAD_PHOTO = 0.02  # a photo's median misclosure / c above this: its orientation is wrong
BAD_BLOCK = 0.05  # the block's median misclosure / c above this: the approximations fail


def diagnose(block: Block, intersected: np.ndarray | None = None,
             ideal: np.ndarray | None = None) -> list[str]:
    """Raise GeometryError for inputs no adjustment can use; else the findings in words.
    intersected: the block's points intersected from its approximate orientations
    (geometry.intersected_points), ideal: its ideal_image_coordinates, when known."""
    if len(block.image) == 0:
        raise GeometryError("the block has no image observations (is image_points.csv empty "
                            "but for its header?)")
    with np.errstate(over="ignore", invalid="ignore"):  # absurd inputs are what it looks for
        _image_size(block)
        _angle_range(block)
        findings = _coordinate_size(block)
        findings += _control_fit(block, intersected)
        return findings + misclosures(block, intersected, ideal)


def _image_size(block: Block) -> None:
    im = block.image
    cam = block.photos.camera[im.photo]
    c = np.abs(block.cameras.focal_mm[cam])
    ratio = np.linalg.norm(im.xy_mm - block.cameras.principal_point_mm[cam], axis=1) / c
    med = float(np.median(ratio))
    if med > PIXELS_FIELD:
        raise GeometryError(
            f"the image coordinates are far too large for the camera(s): their median "
            f"distance from the principal point is {figure(med)} times the camera constant "
            f"(a frame camera images within a few c). Are they in pixels? Image coordinates "
            "are in mm with the origin at the image centre: multiply pixels by the pixel size "
            "and subtract the centre (docs/format.md)")
    bad = np.flatnonzero(ratio > MAX_FIELD)
    if len(bad):
        shown = "; ".join(
            f"photo {block.photos.ids[im.photo[i]]}, point {block.points.ids[im.point[i]]}: "
            f"({im.xy_mm[i, 0]:.6g}, {im.xy_mm[i, 1]:.6g}) mm, {figure(ratio[i])} c from the "
            "principal point" for i in bad[:5])
        raise GeometryError(
            f"{len(bad)} image point(s) lie outside any image format (more than "
            f"{MAX_FIELD:.0f} times the camera constant from the principal point): {shown}"
            f"{'; ...' if len(bad) > 5 else ''}. Correct or remove these measurements")


def _angle_range(block: Block) -> None:
    if block.settings.angle_unit != "rad":
        return
    ang = block.photos.eo[:, 3:]
    bad = np.flatnonzero((np.abs(ang) > 2 * np.pi + 1e-9).any(axis=1))
    if len(bad):
        i = int(bad[0])
        k = int(np.argmax(np.abs(ang[i])))
        raise GeometryError(
            f"photo {block.photos.ids[i]}: {('omega', 'phi', 'kappa')[k]} = {ang[i, k]:.6g} "
            f"with angle_unit = rad ({len(bad)} photo(s) like it): angles in radians lie "
            "within +-2 pi; these look like gon or degrees: set angle_unit in project.toml")


def _coordinate_size(block: Block) -> list[str]:
    xyz = np.vstack([block.photos.eo[:, :3], block.points.xyz])
    big = float(np.nanmax(np.abs(xyz), initial=0.0))
    if big <= EARTH_M:
        return []
    return [f"coordinates up to {big:.3g} m: larger than any map or geocentric coordinate "
            f"(the Earth's radius is 6.4e6 m), and double precision resolves only "
            f"{big * 2.2e-16:.1g} m there: check the units and offsets of the coordinates"]


def _control_fit(block: Block, intersected: np.ndarray | None) -> list[str]:
    """The control against the points intersected from the approximate orientations:
    GeometryError when it fits far better with X and Y exchanged (the columns of the
    control swapped: the fault was blamed on the photos' approximations), a finding when
    it does not fit at all (CRS, units, X/Y order of the control, or the approximations)."""
    eo, pts = block.photos.eo, block.points
    if not np.isfinite(eo).all():
        return []
    xyz = intersected if intersected is not None else \
        intersect(block, eo, np.arange(len(pts)))
    ctrl = (pts.role == "control") & np.isfinite(pts.xyz).all(axis=1) & \
        np.isfinite(xyz).all(axis=1)
    if ctrl.sum() < 3:
        return []
    given, found = pts.xyz[ctrl], xyz[ctrl]
    swapped = given[:, [1, 0, 2]]
    frame = block.frame
    if frame is not None:  # exchange X and Y of the CRS, not of the local frame
        try:
            crs_xyz = frame.from_local(given)
            swapped = frame.to_local(crs_xyz[:, [1, 0, 2]])
        except Exception:  # noqa: BLE001 - swapped coordinates the CRS cannot take
            swapped = np.full_like(given, np.nan)
    d = float(np.median(np.linalg.norm(given[:, :2] - found[:, :2], axis=1)))
    d_swap = float(np.nanmedian(np.linalg.norm(swapped[:, :2] - found[:, :2], axis=1))) \
        if np.isfinite(swapped).any() else np.inf
    extent = float(np.max(np.ptp(found[:, :2], axis=0)))
    sigma = float(np.nanmedian(pts.sigma[ctrl, :2])) if np.isfinite(pts.sigma[ctrl, :2]).any() \
        else 0.0
    if not d > max(0.05 * extent, 10 * sigma):
        return []
    where = f" ({block.source})" if block.source else ""
    if d_swap < 0.1 * d:
        raise GeometryError(
            f"the control's X and Y look swapped{where}: its {int(ctrl.sum())} control points "
            f"lie {d:.4g} m (median) from where the photos' approximate orientations put "
            f"them, {d_swap:.4g} m with X and Y exchanged: exchange the X and Y columns of "
            "the control (ground_points.csv of a native project)")
    return [f"control: its {int(ctrl.sum())} control points lie {d:.4g} m (median) from where "
            "the photos' approximate orientations put them (the block spans "
            f"{extent:.4g} m): check the control's CRS, units and X/Y order, or the "
            "approximations"]


def _misclosure(block: Block, eo: np.ndarray, intersected: np.ndarray | None = None,
                ideal: np.ndarray | None = None) -> np.ndarray:
    """Image misclosure [mm] of every observation of a usable point (NaN for the rest):
    the point (control as given, else intersected from `eo`, or taken from `intersected`,
    the points intersected from `eo`) projected back into the photo, against the ideal
    (distortion-free) observation (`ideal`: ideal_image_coordinates, when known)."""
    ok, _ = usable_points(block)
    pts = block.points
    xyz = pts.xyz.copy()
    given = (pts.role == "control") & np.isfinite(xyz).all(axis=1)
    need = np.flatnonzero(ok & ~given)
    with np.errstate(all="ignore"):
        if ideal is None:
            ideal = ideal_image_coordinates(block)
        xyz[need] = intersect(block, eo, need, ideal) if intersected is None else \
            intersected[need]
        im = block.image
        cam = block.photos.camera[im.photo]
        xy = project(eo, xyz[im.point], block.cameras.focal_mm[cam],
                     block.cameras.principal_point_mm[cam], photo=im.photo)
        d = np.linalg.norm(xy - ideal, axis=1)
    d[~ok[im.point]] = np.nan
    return d


def _photo_medians(block: Block, d: np.ndarray) -> np.ndarray:
    """Median of the finite values of d per photo (NaN for a photo without any)."""
    n = len(block.photos)
    ok = np.isfinite(d)
    photo, v = block.image.photo[ok], d[ok]
    order = np.lexsort((v, photo))
    v = v[order]
    starts = np.searchsorted(photo[order], np.arange(n + 1))
    count = np.diff(starts)
    lo = starts[:-1] + np.maximum(count - 1, 0) // 2
    hi = starts[:-1] + count // 2
    med = np.full(n, np.nan)
    has = count > 0
    med[has] = 0.5 * (v[lo[has]] + v[np.minimum(hi[has], len(v) - 1)])
    return med


def _with_eo(block: Block, eo: np.ndarray) -> Block:
    p = block.photos
    return replace(block, photos=Photos(p.ids, p.camera, p.strip, eo))


def misclosures(block: Block, intersected: np.ndarray | None = None,
                ideal: np.ndarray | None = None) -> list[str]:
    """Findings about the approximate orientations from the rays' misclosures (module
    docstring); GeometryError when the approximations cannot fit at all.  intersected,
    ideal: as for diagnose."""
    eo = block.photos.eo
    if not np.isfinite(eo).all():
        return []
    c = float(np.median(np.abs(block.cameras.focal_mm)))
    d = _misclosure(block, eo, intersected, ideal)
    if not np.isfinite(d).any():
        return []
    block_med = float(np.nanmedian(d))
    if block_med > BAD_BLOCK * c:
        unit = block.settings.angle_unit
        tried = []
        for alt in ANGLE_FACTORS:
            if alt == unit:
                continue
            alt_eo = eo.copy()
            alt_eo[:, 3:] *= ANGLE_FACTORS[alt] / ANGLE_FACTORS[unit]
            tried.append((float(np.nanmedian(_misclosure(block, alt_eo, None, ideal))), alt))
        best, alt = min(tried)
        hint = (f"with angle_unit = \"{alt}\" the misclosure would be {best:.3g} mm: the "
                f"angles look like {alt}, not {unit}" if best < BAD_PHOTO * c else
                "check angle_unit, the rotation convention (docs/format.md) and that the "
                "image and ground coordinates belong to these photos")
        raise GeometryError(
            f"the approximate orientations do not fit the image points: rays miss the "
            f"intersected points by {block_med:.3g} mm in the image (median; camera constant "
            f"{c:.4g} mm); {hint}")
    med = _photo_medians(block, d)
    limit = max(BAD_PHOTO * c, 20 * block_med)
    if not (med > limit).any():
        return []
    # turn the suspects by half a turn, a few rounds (a wrong strip spoils its neighbours'
    # intersections, so its last photos stand out only once the first are turned)
    cur, turned = eo.copy(), np.zeros(len(eo), bool)
    for _ in range(5):
        now = _photo_medians(block, _misclosure(_with_eo(block, cur), cur))
        bad = np.flatnonzero(now > max(BAD_PHOTO * c, 20 * np.nanmedian(now)))
        trial = cur.copy()
        trial[bad, 5] += np.pi
        after = _photo_medians(block, _misclosure(_with_eo(block, trial), trial))
        helps = bad[after[bad] < now[bad]]
        if not len(helps):
            break
        cur[helps, 5] += np.pi
        turned[helps] = ~turned[helps]
    final = _photo_medians(block, _misclosure(_with_eo(block, cur), cur))
    fits = final < BAD_PHOTO * c
    fixed = np.flatnonzero(turned & fits)
    wrong = np.flatnonzero(~fits & (med > limit))
    out = []
    if len(fixed):
        out.append(f"approximations: the rays of {_photos(block, fixed, med)} miss the "
                   f"intersected points in the image (median per photo; the block's median is "
                   f"{block_med:.3g} mm); with kappa + 200 gon they fit ({_range(final[fixed])})"
                   ": kappa is off by half a turn (flight direction reversed?)")
    if len(wrong):
        out.append(f"approximations: the rays of {_photos(block, wrong, med)} miss the "
                   f"intersected points in the image (median per photo; the block's median is "
                   f"{block_med:.3g} mm): their approximate orientations or the identification "
                   "of their points are wrong")
    return out


def _range(v: np.ndarray) -> str:
    lo, hi = float(np.min(v)), float(np.max(v))
    return f"{lo:.3g} mm" if np.isclose(lo, hi, rtol=0.05) else f"{lo:.3g} to {hi:.3g} mm"


def _photos(block: Block, idx: np.ndarray, med: np.ndarray) -> str:
    ids = block.photos.ids
    names = ", ".join(f"{ids[i]} ({med[i]:.3g} mm)" for i in idx[:8])
    more = f" and {len(idx) - 8} more" if len(idx) > 8 else ""
    strips = {str(block.photos.strip[i]) for i in idx}
    whole = [st for st in strips if st and all(
        i in set(idx.tolist()) for i in np.flatnonzero(block.photos.strip == st))]
    where = f" (all of strip {', '.join(sorted(whole))})" if whole else ""
    return f"{len(idx)} photo(s){where}: {names}{more}"
