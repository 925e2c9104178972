"""Everything the on-line bundle has been given, and which of it is in the block.

Photos (with approximate orientations), points (control as given), image points, control
observations, GNSS positions and IMU attitudes, each observation with a status: "held" (not
yet in the block: a point's first ray, a photo the block does not determine yet), "in" (in
the block), "removed".  `state_block` is the Block of what is in: the block a batch
adjustment of the same observations adjusts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.block.photo_block import (
    Block,
    GnssObservations,
    GroundPoints,
    ImagePoints,
    ImuObservations,
    Photos,
)

HELD, IN, REMOVED = "held", "in", "removed"
MIN_PHOTO_POINTS = 3  # a photo enters the block with this many points the block determines


@dataclass(frozen=True)
class StateMaps:
    """Universe indices of the state block's photos, points, image rows, GNSS and IMU rows."""

    photos: np.ndarray
    points: np.ndarray
    image: np.ndarray
    gnss: np.ndarray
    imu: np.ndarray


class Measurements:
    """The photos, points and observations given so far (module docstring).  Indices are
    universe indices: the order in which things were given."""

    def __init__(self, block: Block):
        self.settings, self.cameras, self.frame = block.settings, block.cameras, block.frame
        self.source, self.notes = block.source, list(block.notes)
        self.photo_ids: list[str] = []
        self.photo_at: dict[str, int] = {}
        self.resected: set[int] = set()  # photos oriented on-line by resection from the block
        self.photo_cam: list[int] = []
        self.photo_strip: list = []
        self.photo_eo: list[np.ndarray] = []
        self.photo_in: list[bool] = []
        self.point_ids: list[str] = []
        self.point_at: dict[str, int] = {}
        self.point_xyz: list[np.ndarray] = []
        self.point_sigma: list[np.ndarray] = []
        self.point_role: list[str] = []
        self.point_in: list[bool] = []
        self.ctrl_status: list[str] = []  # "" no control, else held / in / removed
        self.im_photo: list[int] = []
        self.im_point: list[int] = []
        self.im_xy: list[np.ndarray] = []
        self.im_sigma: list[np.ndarray] = []
        self.im_status: list[str] = []
        self.rows_of_photo: list[list[int]] = []
        self.rows_of_point: list[list[int]] = []
        self.g_photo: list[int] = []
        self.g_xyz: list[np.ndarray] = []
        self.g_sigma: list[np.ndarray] = []
        self.g_status: list[str] = []
        self.i_photo: list[int] = []
        self.i_angles: list[np.ndarray] = []
        self.i_sigma: list[np.ndarray] = []
        self.i_status: list[str] = []
        # points set aside (OnlineBundle.set_aside): point -> its last image row then; the
        # point stays out of the block until a ray newer than that is measured
        self.aside: dict[int, int] = {}
        # what the current step gave: its image rows, and points and photos it touched
        self.fresh_rows: set[int] = set()
        self.fresh_points: set[int] = set()
        self.fresh_photos: set[int] = set()
        # (photo_eo, point_xyz, tie) as arrays, until something changes
        self._arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        ph = block.photos
        for i, pid in enumerate(ph.ids):
            self.photo(pid, int(ph.camera[i]), ph.strip[i], ph.eo[i])
        pts = block.points
        for j, pid in enumerate(pts.ids):
            self.point(pid, pts.xyz[j], pts.sigma[j], str(pts.role[j]))
        im = block.image
        sig = im.sigma_xy
        for r in range(len(im)):
            self.image(int(im.photo[r]), int(im.point[r]), im.xy_mm[r], sig[r])
        for r in range(len(block.gnss)):
            self.gnss(int(block.gnss.photo[r]), block.gnss.xyz[r], block.gnss.sigma[r])
        for r in range(len(block.imu)):
            self.imu(int(block.imu.photo[r]), block.imu.angles[r], block.imu.sigma[r])

    # ------------------------------------------------------------ adding
    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(photo approximations (n, 6), point coordinates as given (k, 3), tie mask (k,)):
        arrays of the lists, kept until a photo or point is added or changed (`changed`)."""
        if self._arrays is None:
            self._arrays = (np.array(self.photo_eo, float).reshape(-1, 6),
                            np.array(self.point_xyz, float).reshape(-1, 3),
                            np.array([r == "tie" for r in self.point_role], bool))
        return self._arrays

    def changed(self) -> None:
        self._arrays = None

    def photo(self, pid: str, camera: int, strip, eo) -> int:
        self._arrays = None
        if pid in self.photo_at:
            raise ValueError(f"photo {pid} is known already")
        self.photo_at[pid] = len(self.photo_ids)
        self.photo_ids.append(pid)
        self.photo_cam.append(int(camera))
        self.photo_strip.append(strip)
        self.photo_eo.append(np.asarray(eo, float).copy())
        self.photo_in.append(False)
        self.rows_of_photo.append([])
        return len(self.photo_ids) - 1

    def point(self, pid: str, xyz, sigma, role: str) -> int:
        self._arrays = None
        self.point_at[pid] = len(self.point_ids)
        self.point_ids.append(pid)
        self.point_xyz.append(np.asarray(xyz, float).copy())
        self.point_sigma.append(np.asarray(sigma, float).copy())
        self.point_role.append(role)
        self.point_in.append(False)
        controlled = role == "control" and np.isfinite(self.point_sigma[-1]).any()
        self.ctrl_status.append(HELD if controlled else "")
        self.rows_of_point.append([])
        return len(self.point_ids) - 1

    def point_index(self, pid: str) -> int:
        """The index of point `pid`, a new tie point if it is not known."""
        j = self.point_at.get(pid)
        if j is None:
            j = self.point(pid, np.full(3, np.nan), np.full(3, np.nan), "tie")
        return j

    def photo_index(self, pid: str) -> int:
        i = self.photo_at.get(pid)
        if i is None:
            raise ValueError(f"photo {pid} is not known: give it with add_photo "
                               "(command 'photo') first")
        return i

    def image(self, photo: int, point: int, xy, sigma) -> int:
        for r in self.rows_of_photo[photo]:
            if self.im_point[r] == point and self.im_status[r] != REMOVED:
                raise ValueError(f"point {self.point_ids[point]} is measured on "
                                   f"photo {self.photo_ids[photo]} already (remove it first, "
                                   "or 'remeasure')")
        r = len(self.im_photo)
        self.im_photo.append(photo)
        self.im_point.append(point)
        self.im_xy.append(np.asarray(xy, float).copy())
        self.im_sigma.append(np.broadcast_to(np.asarray(sigma, float), (2,)).copy())
        self.im_status.append(HELD)
        self.rows_of_photo[photo].append(r)
        self.rows_of_point[point].append(r)
        self.fresh_rows.add(r)
        return r

    def gnss(self, photo: int, xyz, sigma) -> int:
        if any(self.g_photo[r] == photo and self.g_status[r] != REMOVED
               for r in range(len(self.g_photo))):
            raise ValueError(f"photo {self.photo_ids[photo]} has a GNSS position "
                               "already (remove it first)")
        self.g_photo.append(photo)
        self.g_xyz.append(np.asarray(xyz, float).copy())
        self.g_sigma.append(np.broadcast_to(np.asarray(sigma, float), (3,)).copy())
        self.g_status.append(HELD)
        self.fresh_photos.add(photo)
        return len(self.g_photo) - 1

    def imu(self, photo: int, angles, sigma) -> int:
        self.i_photo.append(photo)
        self.i_angles.append(np.asarray(angles, float).copy())
        self.i_sigma.append(np.broadcast_to(np.asarray(sigma, float), (3,)).copy())
        self.i_status.append(HELD)
        return len(self.i_photo) - 1

    def control(self, point: int, xyz, sigma) -> None:
        """Control coordinates of a point (sigma NaN: that coordinate is not observed)."""
        if self.ctrl_status[point] in (HELD, IN):
            raise ValueError(f"point {self.point_ids[point]} has control already "
                               "(remove it first)")
        self._arrays = None
        self.point_xyz[point] = np.asarray(xyz, float).copy()
        self.point_sigma[point] = np.asarray(sigma, float).copy()
        self.point_role[point] = "control"
        self.ctrl_status[point] = HELD
        self.fresh_points.add(point)

    def fresh(self) -> list[int]:
        """The held image rows of this step: its own and those of the photos and points it
        touched."""
        rows = set(self.fresh_rows)
        for r in self.fresh_rows:
            rows.update(self.rows_of_photo[self.im_photo[r]])
            rows.update(self.rows_of_point[self.im_point[r]])
        for i in self.fresh_photos:
            rows.update(self.rows_of_photo[i])
        for j in self.fresh_points:
            rows.update(self.rows_of_point[j])
        return sorted(r for r in rows if self.im_status[r] == HELD)

    def clear_fresh(self) -> None:
        self.fresh_rows, self.fresh_points, self.fresh_photos = set(), set(), set()

    def snapshot(self) -> tuple:
        """Every status and role, to put back (`restore`) when a removal cannot be made."""
        return tuple(list(x) for x in (self.im_status, self.ctrl_status, self.g_status,
                                       self.i_status, self.photo_in, self.point_in,
                                       self.point_role)) + (dict(self.aside),)

    def restore(self, snap: tuple) -> None:
        (self.im_status, self.ctrl_status, self.g_status, self.i_status, self.photo_in,
         self.point_in, self.point_role) = (list(x) for x in snap[:7])
        self.aside = dict(snap[7])
        self._arrays = None

    # ------------------------------------------------------------ questions
    def full_control(self, point: int) -> bool:
        return self.ctrl_status[point] in (HELD, IN) and \
            bool(np.isfinite(self.point_sigma[point]).all())

    def waiting(self, point: int) -> bool:
        """Whether a point set aside still waits for a new ray."""
        last = self.aside.get(point)
        return last is not None and max(self.live_rays(point), default=-1) <= last

    def live_rays(self, point: int) -> list[int]:
        """The image rows of a point that are not removed."""
        return [r for r in self.rows_of_point[point] if self.im_status[r] != REMOVED]

    def gnss_of(self, photo: int) -> list[int]:
        return [r for r in range(len(self.g_photo)) if self.g_photo[r] == photo
                and self.g_status[r] != REMOVED]

    def imu_of(self, photo: int) -> list[int]:
        return [r for r in range(len(self.i_photo)) if self.i_photo[r] == photo
                and self.i_status[r] != REMOVED]

    # ------------------------------------------------------------ the block
    def state_block(self, eo: np.ndarray, xyz: np.ndarray) -> tuple[Block, StateMaps]:
        """The Block of the observations in the block, photos and points in universe order,
        image rows by photo (then as given); eo (n_photos, 6) and xyz (n_points, 3) the
        approximations (the current estimates) of the universe's photos and points."""
        photos = np.flatnonzero(self.photo_in)
        points = np.flatnonzero(self.point_in)
        pmap = np.full(len(self.photo_ids), -1)
        pmap[photos] = np.arange(len(photos))
        qmap = np.full(len(self.point_ids), -1)
        qmap[points] = np.arange(len(points))
        rows = np.array([r for i in photos for r in self.rows_of_photo[i]
                         if self.im_status[r] == IN], dtype=np.int64)
        im_photo = np.asarray(self.im_photo, np.int64)
        im_point = np.asarray(self.im_point, np.int64)
        xy = np.array(self.im_xy).reshape(-1, 2)
        sig = np.array(self.im_sigma).reshape(-1, 2)
        image = ImagePoints(pmap[im_photo[rows]], qmap[im_point[rows]], xy[rows],
                            np.sqrt(np.mean(sig[rows] ** 2, axis=1)) if len(rows)
                            else np.zeros(0), sigma_xy_mm=sig[rows])
        ctrl = np.array([self.ctrl_status[j] == IN for j in points], bool)
        role = np.array([self.point_role[j] if self.point_role[j] != "control" or c
                         else "tie" for j, c in zip(points, ctrl, strict=True)], dtype=object)
        given = np.array([self.point_xyz[j] for j in points]).reshape(-1, 3)
        known = (role != "tie")[:, None] & np.isfinite(given)
        pxyz = np.where(known, given, xyz[points])
        psig = np.where(ctrl[:, None], np.array([self.point_sigma[j] for j in points])
                        .reshape(-1, 3), np.nan)
        gpts = GroundPoints([self.point_ids[j] for j in points], pxyz, psig, role)
        cam = np.asarray(self.photo_cam, np.int64)
        strip = np.array(self.photo_strip, dtype=object)
        ph = Photos([self.photo_ids[i] for i in photos], cam[photos], strip[photos],
                    eo[photos])
        g = np.array([r for r in range(len(self.g_photo)) if self.g_status[r] == IN
                      and self.photo_in[self.g_photo[r]]], np.int64)
        gnss = GnssObservations(pmap[np.asarray(self.g_photo, np.int64)[g]] if len(g)
                                else np.zeros(0, np.int64),
                                np.array([self.g_xyz[r] for r in g]).reshape(-1, 3),
                                np.array([self.g_sigma[r] for r in g]).reshape(-1, 3))
        u = np.array([r for r in range(len(self.i_photo)) if self.i_status[r] == IN
                      and self.photo_in[self.i_photo[r]]], np.int64)
        imu = ImuObservations(pmap[np.asarray(self.i_photo, np.int64)[u]] if len(u)
                              else np.zeros(0, np.int64),
                              np.array([self.i_angles[r] for r in u]).reshape(-1, 3),
                              np.array([self.i_sigma[r] for r in u]).reshape(-1, 3))
        block = Block(self.settings, self.cameras, ph, image, gpts, source=self.source,
                      notes=list(self.notes), frame=self.frame, gnss=gnss, imu=imu)
        return block, StateMaps(photos, points, rows, g, u)
