"""Which held observations enter the on-line bundle and which leave it: the bookkeeping of
the statuses in Measurements (online/bundle.py tests and factors what these decide)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from baarda.kinds import GNSS, IMU
from baarda.online.approximations import prune, why_held
from baarda.online.measurements import HELD, IN, MIN_PHOTO_POINTS, REMOVED, Measurements

MAX_HELD_PHOTOS = 50  # held photos looked at together when one is added


def entering(m: Measurements, has_orientation: Callable[[int], bool]) -> dict:
    """The held observations that enter the block now: the photos of this step and the
    held photos connected to them through held points, with the points they see, pruned
    to those that determine each other (`prune`), with every held row between them and
    the block, the control of entering points and the GNSS/IMU of entering photos.
    Returns {kind name: rows (image, GNSS, IMU) or points (control), "photos": new
    photos, "points": new points} or {} when nothing enters."""
    held = m.fresh()
    cand = {i for i in m.fresh_photos if not m.photo_in[i]} | \
        {m.im_photo[r] for r in held if not m.photo_in[m.im_photo[r]]}
    frontier = list(cand)
    while frontier and len(cand) < MAX_HELD_PHOTOS:  # a strip measured before it holds
        i = frontier.pop()
        for r in m.rows_of_photo[i]:
            j = m.im_point[r]
            if m.im_status[r] != HELD or m.point_in[j]:
                continue
            for x in m.rows_of_point[j]:
                k = m.im_photo[x]
                if m.im_status[x] == HELD and not m.photo_in[k] and k not in cand:
                    cand.add(k)
                    frontier.append(k)
    photos = {i for i in cand if has_orientation(i)}
    points = {m.im_point[r] for r in held if not m.point_in[m.im_point[r]]}
    points |= {m.im_point[r] for i in photos for r in m.rows_of_photo[i]
               if m.im_status[r] == HELD and not m.point_in[m.im_point[r]]}
    points |= {j for j in m.fresh_points if not m.point_in[j]}
    photos, points = prune(m, photos, points, m.photo_in, m.point_in)

    def photo_ok(i):
        return m.photo_in[i] or i in photos

    def point_ok(j):
        return m.point_in[j] or j in points

    rows = set(held) | {r for i in photos for r in m.rows_of_photo[i]} | \
        {r for j in points for r in m.rows_of_point[j]}
    rows = sorted(r for r in rows if m.im_status[r] == HELD and photo_ok(m.im_photo[r])
                  and point_ok(m.im_point[r]))
    ctrl = sorted(j for j in set(points) | m.fresh_points
                  if m.ctrl_status[j] == HELD and point_ok(j))
    touched = photos | m.fresh_photos
    gnss = [r for i in sorted(touched) for r in m.gnss_of(i)
            if m.g_status[r] == HELD and photo_ok(i)]
    imu = [r for i in sorted(touched) for r in m.imu_of(i)
           if m.i_status[r] == HELD and photo_ok(i)]
    if not (rows or ctrl or gnss or imu):
        return {}
    return {"image": rows, "control": ctrl, GNSS.name: gnss, IMU.name: imu,
            "photos": sorted(photos), "points": sorted(points)}


def mark(m: Measurements, group: dict) -> None:
    """The group (`entering`) is in the block."""
    for kind, status in (("image", m.im_status), ("control", m.ctrl_status),
                         (GNSS.name, m.g_status), (IMU.name, m.i_status)):
        for r in group[kind]:
            status[r] = IN
    for i in group["photos"]:
        m.photo_in[i] = True
    for j in group["points"]:
        m.point_in[j] = True


def mark_in(m: Measurements) -> None:
    """Every held observation between photos and points in the block is in (the first
    adjustment)."""
    for r in range(len(m.im_status)):
        if m.im_status[r] == HELD and m.photo_in[m.im_photo[r]] \
                and m.point_in[m.im_point[r]]:
            m.im_status[r] = IN
    for j in range(len(m.ctrl_status)):
        if m.ctrl_status[j] == HELD and m.point_in[j]:
            m.ctrl_status[j] = IN
    for st, ph in ((m.g_status, m.g_photo), (m.i_status, m.i_photo)):
        for r in range(len(st)):
            if st[r] == HELD and m.photo_in[ph[r]]:
                st[r] = IN


def leaving(m: Measurements) -> None:
    """After a removal: points and photos the block no longer determines leave it,
    their observations held again (until a determination of their own)."""
    changed = True
    while changed:
        changed = False
        for j in np.flatnonzero(m.point_in):
            rays = [r for r in m.live_rays(int(j)) if m.photo_in[m.im_photo[r]]]
            if not (len(rays) >= 2 or (rays and m.full_control(int(j)))):
                m.point_in[j] = False
                changed = True
        for i in np.flatnonzero(m.photo_in):
            pts = {m.im_point[r] for r in m.rows_of_photo[i] if m.im_status[r] != REMOVED
                   and m.point_in[m.im_point[r]]}
            if len(pts) < MIN_PHOTO_POINTS:
                m.photo_in[i] = False
                changed = True
    for r in range(len(m.im_status)):
        if m.im_status[r] == IN and not (m.photo_in[m.im_photo[r]]
                                         and m.point_in[m.im_point[r]]):
            m.im_status[r] = HELD
    for j in range(len(m.ctrl_status)):
        if m.ctrl_status[j] == IN and not m.point_in[j]:
            m.ctrl_status[j] = HELD
    for st, ph in ((m.g_status, m.g_photo), (m.i_status, m.i_photo)):
        for r in range(len(st)):
            if st[r] == IN and not m.photo_in[ph[r]]:
                st[r] = HELD


def held_words(m: Measurements) -> list[str]:
    """What of this step is held, in words."""
    out = []
    said: dict[int, str] = {}  # per photo, worked out once
    for r in sorted(m.fresh_rows):
        if m.im_status[r] != HELD:
            continue
        i, j = m.im_photo[r], m.im_point[r]
        if not m.photo_in[i]:
            if i not in said:
                said[i] = why_held(m, i)
            why = said[i]
        else:
            why = "its first ray" if len(m.live_rays(j)) < 2 else \
                "its point is not determined yet"
        out.append(f"point {m.point_ids[j]} on photo {m.photo_ids[i]}: {why}")
    return out
