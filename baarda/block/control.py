"""A block with its control replaced by the points of a control file (`--control FILE`,
`baarda.read(control=...)`; the file is read by io/control_file.py).

The file's points replace the input's control: every control point of the input becomes a
tie point, and each point of the file whose id is a point of the block becomes control
(sigma 0: fixed) or a check point as the file says.  Ids of the file that no photo measures
are named in a note; a file of which no id matches is an error.

The input's own coordinates (the object points and orientations of a PhotoModeler export,
for instance) may be in another frame than the control: PhotoModeler's are shifted by its
own origin.  When the input's coordinates of the matched points differ from the file's by
more than 5 % of the control's extent (plus three standard deviations), they are not
approximations of this frame: the orientations and the tie points' coordinates are dropped
and found again by space resection from the control and intersection, as DBAT does.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baarda.block.photo_block import Block
from baarda.block.rotation import angles_from_matrix, rotation_matrix, similarity
from baarda.errors import ProjectError

# a reader's note about the input's own control starts with this: --control replaces it
INPUT_CONTROL = "the input's control: "


def without_input_control_notes(notes) -> list[str]:
    """`notes` less the readers' notes about the input's own control (INPUT_CONTROL): what
    replaces the control (with_control, gcp.add_gcps) drops them."""
    return [n for n in notes if not n.startswith(INPUT_CONTROL)]


def with_control(block: Block, ids: list[str], xyz: np.ndarray, sigma: np.ndarray,
                 role: np.ndarray, source: str) -> Block:
    """The block with the points (ids, xyz (k, 3) [m], sigma (k, 3) [m, 0: fixed, NaN for
    check points], role 'control' | 'check') of the control file `source` as its control
    (module docstring)."""
    pts = block.points
    index = block.point_index
    rows: list[int] | np.ndarray = [k for k, p in enumerate(ids) if p in index]
    unmatched = [p for p in ids if p not in index]
    if not rows:
        sample = ", ".join(pts.ids[:5]) + (", ..." if len(pts) > 5 else "")
        raise ProjectError(source, f"none of its {len(ids)} point id(s) ({', '.join(ids[:5])}"
                           f"{', ...' if len(ids) > 5 else ''}) is a point of "
                           f"{block.source or block.settings.name} (its ids: {sample}); "
                           "control points are matched by id")
    j = np.array([index[ids[k]] for k in rows], dtype=np.int64)
    rows = np.array(rows, dtype=np.int64)
    notes = without_input_control_notes(block.notes)  # replaced
    old_ctrl = pts.role == "control"
    new_xyz, new_sig = pts.xyz.copy(), np.full_like(pts.sigma, np.nan)
    new_role = np.where(old_ctrl, "tie", pts.role).astype(object)
    eo = block.photos.eo

    # the input's own coordinates of the matched points against the file's
    own = pts.xyz[j]
    ok = np.isfinite(own).all(axis=1)
    if ok.any():
        diff = float(np.max(np.abs(own[ok] - xyz[rows][ok])))
        extent = float(np.max(np.ptp(xyz[rows][ok], axis=0)))
        spread = float(np.nanmax(sigma[rows], initial=0.0))
        if diff > 0.05 * extent + 3 * spread:
            new_xyz, eo, text = into_frame(pts.xyz, eo, own[ok], xyz[rows][ok])
            new_role = np.where(new_role == "check", "tie", new_role).astype(object)
            notes.append(f"the input's coordinates of {source}'s points differ from the file's "
                         f"by up to {diff:.4g} m (another frame): {text}")
    new_xyz[j] = xyz[rows]
    new_sig[j] = np.where(role[rows, None] == "control", sigma[rows], np.nan)
    new_role[j] = role[rows]
    fixed = int(((role[rows] == "control") & (sigma[rows] == 0).all(axis=1)).sum())
    n_ctrl = int((role[rows] == "control").sum())
    notes.append(f"control from {source}: {n_ctrl} control point(s)"
                 + (f" ({fixed} fixed)" if fixed else "")
                 + (f", {len(rows) - n_ctrl} check point(s)" if len(rows) > n_ctrl else "")
                 + (f"; it replaces the input's {int(old_ctrl.sum())} control point(s)"
                    if old_ctrl.any() else ""))
    if unmatched:
        notes.append(f"{len(unmatched)} point(s) of {source} are not points of the input "
                     "(measured on no photo) and are not used: " + ", ".join(unmatched[:20])
                     + (", ..." if len(unmatched) > 20 else ""))
    weighted = sigma[rows][role[rows] == "control"]
    weighted = weighted[(weighted > 0).all(axis=1)]
    settings = replace(block.settings, datum="control", free_datum=None,
                       sigma_control_m=(tuple(float(v) for v in np.median(weighted, axis=0))  # type: ignore[arg-type]  # 3 axes
                                        if len(weighted) else block.settings.sigma_control_m))
    points = replace(pts, xyz=new_xyz, sigma=new_sig, role=new_role)
    photos = replace(block.photos, eo=eo)
    return replace(block, settings=settings, points=points, photos=photos, notes=notes)


def into_frame(xyz: np.ndarray, eo: np.ndarray, src: np.ndarray,
                dst: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """The input's point coordinates and orientations carried into the control's frame by
    the similarity that fits `src` (the input's coordinates of the matched points) to `dst`
    (the file's), when three or more points not on a line give it; else dropped (NaN: space
    resection from the control and intersection find them again).  With a text for the
    note."""
    if len(src) >= 3:
        spread = np.linalg.svd(src - src.mean(axis=0), compute_uv=False)
        if spread[1] > 1e-6 * max(spread[0], 1e-300):
            s, r, t = similarity(src, dst)
            rms = float(np.sqrt(np.mean(np.sum((s * src @ r.T + t - dst) ** 2, axis=1))))
            out = s * xyz @ r.T + t
            moved = eo.copy()
            moved[:, :3] = s * eo[:, :3] @ r.T + t
            moved[:, 3:] = angles_from_matrix(r @ rotation_matrix(eo[:, 3], eo[:, 4],
                                                                    eo[:, 5]))
            return out, moved, (f"its orientations and points are carried into the control's "
                                f"frame by a similarity from {len(src)} points (scale "
                                f"{s:.6g}, RMS {rms:.3g} m) and serve as approximations")
    return (np.full_like(xyz, np.nan), np.full_like(eo, np.nan),
            "its orientations and points are dropped and found again by space resection "
            "from the control and intersection")


CHECK_ALTERNATE = ("alternate", "every-other")


def with_check_points(block: Block, spec) -> Block:
    """The block with control points turned into check points: `spec` a list of point ids
    (or a comma-separated string of them; an OpenSfM GCP renamed 'gcp ID' is found by its
    ID too), or "alternate" / "every-other": every second control point with all three
    coordinates in the order read (the 2nd, 4th, ...).  ProjectError for an id that is not
    a control point (pipeline.read_configured applies it: `--check-gcp`)."""
    pts = block.points
    ctrl = pts.role == "control"
    if isinstance(spec, str) and spec.strip() in CHECK_ALTERNATE:
        full = np.flatnonzero(ctrl & np.isfinite(pts.xyz).all(axis=1))
        chosen = set(full[1::2].tolist())
    else:
        names = [p.strip() for p in spec.split(",")] if isinstance(spec, str) else \
            [str(p) for p in spec]
        index = block.point_index
        chosen = set()
        for name in (n for n in names if n):
            found = [j for j in (index.get(name), index.get(f"gcp {name}"))
                     if j is not None and ctrl[j]]
            j = found[0] if found else None
            if j is None:
                raise ProjectError("command line", f"--check-gcp: {name} is not a control "
                                   "point of " + (block.source or block.settings.name))
            chosen.add(j)
    if not chosen:
        return block
    role = pts.role.copy()
    role[sorted(chosen)] = "check"
    names = ", ".join(pts.ids[j] for j in sorted(chosen))
    return replace(block, points=replace(pts, role=role), notes=list(block.notes) + [
        f"{len(chosen)} control point(s) used as check points: {names}"])
