"""The COLMAP sparse model as arrays: cameras, images with their keypoints, 3D points with
their tracks (one row per image / point in file order, never one Python object per point).

Variable-length lists are stored flat with offsets: the keypoints of image row k are rows
``offsets[k]:offsets[k + 1]`` of `xys` and `point3D_ids`; the track of point row j is
``offsets[j]:offsets[j + 1]`` of `image_ids` and `point2D_idxs`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# model id -> (name, number of parameters)
MODELS = {0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4), 2: ("SIMPLE_RADIAL", 4),
          3: ("RADIAL", 5), 4: ("OPENCV", 8), 5: ("OPENCV_FISHEYE", 8), 6: ("FULL_OPENCV", 12),
          7: ("FOV", 5), 8: ("SIMPLE_RADIAL_FISHEYE", 4), 9: ("RADIAL_FISHEYE", 5),
          10: ("THIN_PRISM_FISHEYE", 12), 11: ("RAD_TAN_THIN_PRISM_FISHEYE", 16)}
MODEL_ID = {name: (i, n) for i, (name, n) in MODELS.items()}
FILES = ("cameras", "images", "points3D")


def lookup(ids: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Row in `ids` (distinct) of every value of `wanted`, -1 where it is not there."""
    ids = np.asarray(ids, np.int64)
    wanted = np.asarray(wanted, np.int64)
    if not len(ids):
        return np.full(wanted.shape, -1, np.int64)
    lo, hi = int(ids.min()), int(ids.max())
    if hi - lo <= 4 * len(ids) + 1024:  # compact ids (COLMAP's are 1..n): a table
        table = np.full(hi - lo + 1, -1, np.int64)
        table[ids - lo] = np.arange(len(ids))
        inside = (wanted >= lo) & (wanted <= hi)
        return np.where(inside, table[np.where(inside, wanted - lo, 0)], -1)
    order = np.argsort(ids, kind="stable")
    srt = ids[order]
    pos = np.minimum(np.searchsorted(srt, wanted), len(srt) - 1)
    return np.where(srt[pos] == wanted, order[pos], -1)


def first_repeated(ids: np.ndarray) -> int:
    """Row of the first value (in row order) that appeared in an earlier row, or -1."""
    order = np.argsort(ids, kind="stable")
    srt = ids[order]
    rep = order[1:][srt[1:] == srt[:-1]]
    return int(rep.min()) if len(rep) else -1


def _offsets(counts: list[int] | np.ndarray) -> np.ndarray:
    out = np.zeros(len(counts) + 1, np.int64)
    np.cumsum(counts, out=out[1:])
    return out


@dataclass
class ColmapCamera:
    model: str  # COLMAP's model name, e.g. "PINHOLE"
    width: int  # pixels
    height: int  # pixels
    params: np.ndarray  # the model's parameters (focal lengths, principal point in pixels)


@dataclass(frozen=True, eq=False)
class ColmapImages:
    """The images of a model, one row per image in file order, with all their keypoints."""

    ids: np.ndarray  # (n,) int64 IMAGE_ID
    qvec: np.ndarray  # (n, 4) qw, qx, qy, qz: rotation world -> camera
    tvec: np.ndarray  # (n, 3) translation world -> camera (model units)
    camera_id: np.ndarray  # (n,) int64 CAMERA_ID
    names: list[str]  # (n,) file names
    offsets: np.ndarray  # (n + 1,) int64 keypoints of row k: offsets[k]:offsets[k + 1]
    xys: np.ndarray  # (K, 2) keypoint column, row [pixels, origin at the upper-left corner]
    point3D_ids: np.ndarray  # (K,) int64 POINT3D_ID of each keypoint, -1 = none

    @classmethod
    def from_lists(cls, ids, qvec, tvec, camera_id, names, xys: list[np.ndarray],
                   point3D_ids: list[np.ndarray]) -> ColmapImages:
        """From per-image keypoint arrays (xys (k, 2) and point3D_ids (k,) of each image)."""
        n = len(ids)
        return cls(np.asarray(ids, np.int64).reshape(n), np.asarray(qvec, float).reshape(n, 4),
                   np.asarray(tvec, float).reshape(n, 3),
                   np.asarray(camera_id, np.int64).reshape(n), list(names),
                   _offsets([len(p) for p in point3D_ids]),
                   np.concatenate([np.asarray(x, float).reshape(-1, 2) for x in xys])
                   if n else np.zeros((0, 2)),
                   np.concatenate([np.asarray(p, np.int64) for p in point3D_ids])
                   if n else np.zeros(0, np.int64))

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def keypoint_counts(self) -> np.ndarray:
        """(n,) number of keypoints of each image."""
        return np.diff(self.offsets)

    def keypoints(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """xys (k, 2) [pixels] and point3D_ids (k,) of image row k (views)."""
        s = slice(self.offsets[k], self.offsets[k + 1])
        return self.xys[s], self.point3D_ids[s]

    def image_of_keypoint(self) -> np.ndarray:
        """(K,) image row of every keypoint."""
        return np.repeat(np.arange(len(self.ids)), self.keypoint_counts)

    def rows(self, ids) -> np.ndarray:
        """Image row of each IMAGE_ID in `ids`, -1 where there is none."""
        return lookup(self.ids, ids)


@dataclass(frozen=True, eq=False)
class ColmapPoints:
    """The 3D points of a model, one row per point in file order, with their tracks."""

    ids: np.ndarray  # (m,) int64 POINT3D_ID
    xyz: np.ndarray  # (m, 3) coordinates (model units)
    rgb: np.ndarray  # (m, 3) uint8 colour
    error: np.ndarray  # (m,) mean reprojection error [pixels]
    offsets: np.ndarray  # (m + 1,) int64 track of row j: offsets[j]:offsets[j + 1]
    image_ids: np.ndarray  # (T,) int64 IMAGE_ID of each track element
    point2D_idxs: np.ndarray  # (T,) int64 keypoint index within that image (0-based)

    @classmethod
    def from_lists(cls, ids, xyz, rgb, error, image_ids: list[np.ndarray],
                   point2D_idxs: list[np.ndarray]) -> ColmapPoints:
        """From per-point track arrays."""
        m = len(ids)
        return cls(np.asarray(ids, np.int64).reshape(m), np.asarray(xyz, float).reshape(m, 3),
                   np.asarray(rgb, np.uint8).reshape(m, 3), np.asarray(error, float).reshape(m),
                   _offsets([len(t) for t in image_ids]),
                   np.concatenate([np.asarray(t, np.int64) for t in image_ids])
                   if m else np.zeros(0, np.int64),
                   np.concatenate([np.asarray(t, np.int64) for t in point2D_idxs])
                   if m else np.zeros(0, np.int64))

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def track_lengths(self) -> np.ndarray:
        """(m,) number of track elements of each point."""
        return np.diff(self.offsets)

    def track(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """image_ids and point2D_idxs of the track of point row j (views)."""
        s = slice(self.offsets[j], self.offsets[j + 1])
        return self.image_ids[s], self.point2D_idxs[s]

    def point_of_element(self) -> np.ndarray:
        """(T,) point row of every track element."""
        return np.repeat(np.arange(len(self.ids)), self.track_lengths)

    def rows(self, ids) -> np.ndarray:
        """Point row of each POINT3D_ID in `ids`, -1 where there is none."""
        return lookup(self.ids, ids)


def _no_images() -> ColmapImages:
    return ColmapImages.from_lists([], [], [], [], [], [], [])


def _no_points() -> ColmapPoints:
    return ColmapPoints.from_lists([], [], [], [], [], [])


@dataclass(frozen=True, eq=False)
class ColmapModel:
    """A COLMAP sparse model: cameras by CAMERA_ID (file order), images, 3D points."""

    cameras: dict[int, ColmapCamera] = field(default_factory=dict)
    images: ColmapImages = field(default_factory=_no_images)
    points: ColmapPoints = field(default_factory=_no_points)
