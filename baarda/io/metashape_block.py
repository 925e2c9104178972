"""A Metashape chunk (io/metashape_chunk.py: `Chunk`, `TiePoints`) as a Block: cameras,
photos in the reference system (or, for a chunk in a CRS, its local east-north-up frame),
markers as control, check and tie points, image points in mm (conventions in
io/metashape_chunk.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.block.rotation import FLIP, angles_from_matrix
from baarda.errors import ProjectError
from baarda.io.metashape_chunk import (
    DEFAULT_PROJECTION_PX,
    DEFAULT_TIE_PX,
    IMAGE_SUFFIXES,
    Chunk,
    TiePoints,
)


def to_block(ch: Chunk, ties: TiePoints | None, *, pixel_mm: float, sigma_px: float | None,
             name: str, all_cameras: list[str] | None = None) -> Block:
    """The Block of a chunk and its tie points (module docstring).  `all_cameras`: the ids
    of every camera of the chunk (enabled or not), to tell a projection on a camera left
    out from one on a camera that does not exist."""
    where = ch.where
    notes = list(ch.notes)
    index = {c: i for i, c in enumerate(ch.camera_ids)}
    every = set(all_cameras or []) | set(ch.camera_ids)
    sensor_ids = sorted(set(ch.camera_sensor), key=list(ch.sensors).index)
    sens = [ch.sensors[s] for s in sensor_ids]
    pix = np.array([s.pixel_mm or pixel_mm for s in sens])
    if any(s.pixel_mm is None for s in sens):
        notes.append(f"Metashape: no pixel size in the sensor: nominal {pixel_mm:g} mm")
    for s in sens:
        if s.dropped:
            notes.append(f"sensor {s.label}: " + ", ".join(f"{k} = {v:g}" for k, v in
                                                           s.dropped.items())
                         + " not held (baarda's brown_forward has no K4, P3, P4 or skew): "
                         "the camera is approximated without them")
    cam_of = np.array([sensor_ids.index(s) for s in ch.camera_sensor])
    cameras = Cameras([s.label if [t.label for t in sens].count(s.label) == 1 else
                       f"{s.label}#{s.id}" for s in sens],
                      np.array([s.c_px for s in sens]) * pix,
                      np.array([[s.pp_px[0], -s.pp_px[1]] for s in sens]) * pix[:, None],
                      np.full(len(sens), "brown_forward", dtype=object),
                      np.array([s.coef for s in sens]), None, pixel_mm=pix)
    r_cam = ch.rotation @ ch.camera_pose[:, :3, :3] @ FLIP
    x0 = ch.to_crs(ch.camera_pose[:, :3, 3])
    frame = _geocentric_frame(ch)
    if frame is not None:  # the transform gives earth-centred coordinates: into the frame
        r_cam = frame.rot @ r_cam
        x0 = (x0 - frame.origin_ecef) @ frame.rot.T
    names = [Path(s).stem if Path(s).suffix.lower() in IMAGE_SUFFIXES else s
             for s in ch.camera_labels]
    if len(set(names)) < len(names):
        names = list(ch.camera_labels)
    if len(set(names)) < len(names):
        names = [f"{lab}#{cid}" for lab, cid in zip(ch.camera_labels, ch.camera_ids, strict=True)]
    photos = Photos(names, cam_of, np.full(len(names), "", dtype=object),
                    np.column_stack([x0, angles_from_matrix(r_cam)]))
    tie_px = sigma_px if sigma_px is not None else ch.accuracy.get("accuracy_tiepoints",
                                                                    DEFAULT_TIE_PX)
    mark_px = sigma_px if sigma_px is not None else ch.accuracy.get("accuracy_projections",
                                                                     DEFAULT_PROJECTION_PX)
    # marker projections
    mindex = {m: k for k, m in enumerate(ch.marker_ids)}
    rows = []
    out_of = 0
    for mid, cid, u, v, line in ch.projections:  # type: ignore[misc]
        if cid not in index:
            if cid not in every:
                raise ProjectError(where, f"marker {mid}: a projection on camera {cid}, "
                                   f"which the chunk does not have", line, "camera_id")
            out_of += 1
            continue
        rows.append((index[cid], mindex[mid], u, v))
    if out_of:
        notes.append(f"{out_of} marker projection(s) on cameras left out not used")
    if ch.unpinned:
        notes.append(f"{ch.unpinned} marker projection(s) not pinned (placed by Metashape, "
                     "not confirmed on the image): used as measured")
    mp = np.array(rows, float).reshape(-1, 4)
    seen = np.bincount(mp[:, 1].astype(int), minlength=len(ch.marker_ids))
    keep_m = seen > 0
    if (~keep_m).any():
        notes.append(f"{int((~keep_m).sum())} marker(s) without a projection left out: "
                     + ", ".join(np.array(ch.marker_labels)[~keep_m][:10]))
    m_new = np.cumsum(keep_m) - 1
    has_ref = np.isfinite(ch.marker_xyz).all(axis=1)
    role = np.where(has_ref & ch.marker_enabled, "control",
                    np.where(has_ref, "check", "tie")).astype(object)
    pt_ids = [str(s) for s in np.array(ch.marker_labels, dtype=object)[keep_m]]
    xyz = ch.marker_xyz[keep_m] if frame is None else frame.to_local(ch.marker_xyz[keep_m])
    sig = np.where((role == "control")[:, None], ch.marker_sigma, np.nan)[keep_m]
    roles = role[keep_m]
    photo = mp[:, 0].astype(np.int64)
    point = m_new[mp[:, 1].astype(np.int64)]
    uv = mp[:, 2:4]
    sigma = np.full(len(mp), mark_px)
    n_mark = len(mp)
    if ties is not None:
        if set(ties.ids) & set(pt_ids):
            raise ProjectError(ties.source, "tie point ids repeat marker labels: "
                               + ", ".join(sorted(set(ties.ids) & set(pt_ids))[:5]))
        txyz = ties.xyz if ties.in_crs else ch.to_crs(ties.xyz)
        if frame is not None:
            txyz = (txyz - frame.origin_ecef) @ frame.rot.T
        tcam = np.array([index.get(c, -1) for c in ties.camera], np.int64)
        bad = [c for c in ties.camera if c not in every]
        if bad:
            raise ProjectError(ties.source, f"projections on camera {bad[0]}, which the chunk "
                               "does not have", None, "camera_id")
        ok = tcam >= 0
        if not ok.all():
            notes.append(f"{int((~ok).sum())} tie point projection(s) on cameras left out "
                         "not used")
        base = len(pt_ids)
        pt_ids += ties.ids
        xyz = np.vstack([xyz, txyz])
        sig = np.vstack([sig, np.full((len(ties.ids), 3), np.nan)])
        roles = np.concatenate([roles, np.full(len(ties.ids), "tie", dtype=object)])
        photo = np.concatenate([photo, tcam[ok]])
        point = np.concatenate([point, base + ties.point[ok]])
        uv = np.vstack([uv, ties.uv[ok]])
        sigma = np.concatenate([sigma, np.full(int(ok.sum()), tie_px)])
    cam = cam_of[photo]
    w = np.array([s.width for s in sens], float)[cam]
    h = np.array([s.height for s in sens], float)[cam]
    p = pix[cam]
    xy = np.column_stack([(uv[:, 0] - w / 2) * p, (h / 2 - uv[:, 1]) * p])
    image = ImagePoints(photo, point, xy, sigma * p)
    points = GroundPoints(pt_ids, xyz, sig, roles)
    n_ctrl, n_chk = int(np.sum(roles == "control")), int(np.sum(roles == "check"))
    notes.insert(0, f"Metashape chunk '{ch.label}': {len(names)} camera(s), "
                 f"{len(ch.marker_ids)} marker(s) ({n_ctrl} control, {n_chk} check), "
                 f"{n_mark} marker projection(s) at {mark_px:g} px, "
                 + (f"{len(ties.ids)} tie point(s) from {ties.source} at {tie_px:g} px"
                    if ties is not None else "no tie points")
                 + f"; chunk transform scale {ch.scale:.6g}"
                 + (f", CRS {ch.crs}" if ch.crs else ", no CRS (local or none)"))
    settings = Settings(name=name, angle_unit="deg",
                        sigma_image_um=float(tie_px * pix[0] * 1e3), crs=ch.crs,
                        datum="control" if n_ctrl else "free",
                        calibration_free=tuple(s.free for s in sens))
    if n_ctrl:
        settings.sigma_control_m = tuple(float(v) for v in  # type: ignore[assignment]
                                         np.median(sig[roles == "control"], axis=0))
    if frame is not None:
        notes.append(f"the chunk transform gives earth-centred coordinates ({ch.crs}): the "
                     "block is adjusted in a local east-north-up frame at the markers' mean, "
                     "results converted back to the CRS")
    return Block(settings, cameras, photos, image, points, source=where, notes=notes,
                 frame=frame)


def _geocentric_frame(ch: Chunk):
    """The LocalFrame of a chunk in a geographic or projected CRS (Metashape's transform then
    maps to earth-centred coordinates on the CRS's ellipsoid; its references are in the
    CRS), at the mean of the markers' references; None for a chunk without a CRS."""
    if ch.crs is None:
        return None
    from baarda.block.crs import LocalFrame

    ref = ch.marker_xyz[np.isfinite(ch.marker_xyz).all(axis=1)]
    if not len(ref):
        raise ProjectError(ch.where, f"the chunk is in {ch.crs} but no marker has reference "
                           "coordinates: the local frame cannot be placed", None, "markers")
    try:
        return LocalFrame(ch.crs, ref.mean(axis=0))
    except ProjectError as e:
        raise ProjectError(ch.where, f"the chunk's CRS {ch.crs}: {e.detail}", None,
                           "reference") from None
