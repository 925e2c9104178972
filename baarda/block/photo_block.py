"""The block: cameras, photos, image observations and ground points as NumPy arrays.

Internal units: object coordinates in metres, angles in radians, image coordinates in
millimetres, image standard deviations in millimetres.  Readers convert from the file
units (µm, gon, deg) on the way in; writers convert back.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from baarda.options import DEFAULT_TESTS

if TYPE_CHECKING:
    from baarda.block.crs import LocalFrame



@dataclass
class Settings:
    """Project settings from project.toml."""

    name: str = "block"
    angle_unit: str = "gon"
    sigma_image_um: float = 5.0
    sigma_control_m: tuple[float, float, float] = (0.05, 0.05, 0.05)
    alpha0: float = DEFAULT_TESTS.alpha0
    beta0: float = DEFAULT_TESTS.beta0
    alpha_global: float = DEFAULT_TESTS.alpha_global
    crs: str | None = None
    datum: str = "control"  # control: the control fixes the block; free: minimal constraints
    # the minimal constraints of a free network as its source states them (DBAT's set_datum
    # depend): (id of the photo held, "longest" | "x" | "y" | "z"); None: baarda's choice
    free_datum: tuple[str, str] | None = None
    # camera parameters estimated per camera ("camera") or per camera and strip ("strip":
    # project.toml [calibration] group; pipeline.read splits the cameras)
    calibration_group: str = "camera"
    # per camera: the parameters a self-calibration estimates, as the input states them
    # (project.toml's [calibration] free, or the source program's choice; None: none stated)
    # and, after io/configuration.configure, as the run's resolved options.Config has them
    # (bundle/calibration.py reads them there; the cameras are data only)
    calibration_free: tuple[tuple[str, ...], ...] | None = None
    # GNSS/IMU (docs/format.md [gnss], [imu]): lever arm (m, camera frame) from the
    # projection centre to the antenna; shifts per block or strip and a linear drift per
    # strip as unknowns; IMU boresight misalignment held (identity) or estimated
    gnss_lever_arm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gnss_offsets: str = "none"  # none | block | strip
    gnss_drift: bool = False
    imu_boresight: str = "fixed"  # fixed | estimated
    # the keys project.toml sets ("tests.alpha0", "datum", ...): a command line's value
    # over one of them is noted (io/configuration.py)
    given: frozenset[str] = frozenset()


@dataclass
class Cameras:
    """Interior orientation and camera model of every camera (block/camera.py)."""

    ids: list[str]
    focal_mm: np.ndarray  # (n,) camera constant c
    principal_point_mm: np.ndarray  # (n, 2): x0, y0
    model: np.ndarray | None = None  # (n,) model kind (block/camera.py), None = none
    coefficients: np.ndarray | None = None  # (n, k) the model's params in order, 0-padded
    constants: np.ndarray | None = None  # (n, kc) the model's constants (R0, grid spacing)
    pixel_mm: np.ndarray | None = None  # (n,) pixel size where the source states it (mm)
    # how image coordinates (mm) sit on the image's pixels, as the reader converted them
    # (block/pixels.py converts both ways): (n, 4) column and row (pixels from the upper-left
    # corner of the image, y down) of their origin (NaN: the image's centre, for readers that
    # do not know the image's size), then the width and height of a pixel [mm] as the reader
    # scaled x and y (COLMAP: p and p fx/fy): column = c0 + x / pw, row = r0 - y / ph
    pixel_frame: np.ndarray | None = None
    image_size_px: np.ndarray | None = None  # (n, 2) width, height [px] (NaN: unknown)

    def __len__(self) -> int:
        return len(self.ids)


@dataclass
class Photos:
    ids: list[str]
    camera: np.ndarray  # (n,) index into Cameras
    strip: np.ndarray  # (n,) object array of strip labels
    eo: np.ndarray  # (n, 6): X0, Y0, Z0 [m], omega, phi, kappa [rad] (approximations)
    # the image file the input names for each photo ("" none), as written there (a path
    # relative to the input's folder, or absolute); baarda review shows it
    image: list[str] | None = None

    def __len__(self) -> int:
        return len(self.ids)


@dataclass
class ImagePoints:
    """One row per measured image point (x and y of one point on one photo)."""

    photo: np.ndarray  # (m,) index into Photos
    point: np.ndarray  # (m,) index into GroundPoints
    xy_mm: np.ndarray  # (m, 2)
    sigma_mm: np.ndarray  # (m,) standard deviation of x and of y (RMS of the two)
    model: np.ndarray | None = None  # (m,) stereo model label (twin rays), or None
    sigma_xy_mm: np.ndarray | None = None  # (m, 2) when x and y have their own sigmas

    def __len__(self) -> int:
        return len(self.photo)

    @property
    def sigma_xy(self) -> np.ndarray:
        """(m, 2) standard deviations of x and y in mm."""
        if self.sigma_xy_mm is not None:
            return self.sigma_xy_mm
        return np.repeat(np.asarray(self.sigma_mm, float)[:, None], 2, axis=1)

    def take(self, keep: np.ndarray) -> ImagePoints:
        """The rows `keep` (a boolean mask or indices)."""
        return ImagePoints(self.photo[keep], self.point[keep], self.xy_mm[keep],
                           self.sigma_mm[keep], None if self.model is None else self.model[keep],
                           None if self.sigma_xy_mm is None else self.sigma_xy_mm[keep])


@dataclass
class GroundPoints:
    """Every point of the block: control, check and tie points.

    `xyz` holds the given coordinates of control and check points and approximations
    (or NaN) for tie points; `sigma` is NaN for a coordinate that is not observed, so a
    planimetric control point has sigma Z = NaN and a height point NaN in X and Y.
    """

    ids: list[str]
    xyz: np.ndarray  # (k, 3)
    sigma: np.ndarray  # (k, 3)
    role: np.ndarray  # (k,) object array: 'control', 'check' or 'tie'

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def controlled(self) -> np.ndarray:
        """(k, 3) bool: coordinate enters the adjustment as an observation."""
        return (self.role == "control")[:, None] & np.isfinite(self.sigma)


@dataclass
class Distances:
    """Observed distances between ground points (scale bars, taped distances), in m."""

    ids: list[str]  # a name of each distance (scale bar name or 'A-B')
    point_a: np.ndarray  # (n,) index into GroundPoints
    point_b: np.ndarray  # (n,)
    length_m: np.ndarray  # (n,)
    sigma_m: np.ndarray  # (n,) a-priori standard deviation

    def __len__(self) -> int:
        return len(self.ids)


def no_distances() -> Distances:
    return Distances([], np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0),
                     np.zeros(0))


GNSS_OFFSETS = ("none", "block", "strip")
IMU_BORESIGHT = ("fixed", "estimated")


@dataclass
class GnssObservations:
    """Observed GNSS antenna positions of photos (m, ground frame) with their a-priori
    standard deviations; the antenna is the projection centre plus the lever arm
    (Settings.gnss_lever_arm, camera frame).  time: optional (s)."""

    photo: np.ndarray  # (k,) index into Photos
    xyz: np.ndarray  # (k, 3)
    sigma: np.ndarray  # (k, 3)
    time: np.ndarray | None = None  # (k,)

    def __len__(self) -> int:
        return len(self.photo)


@dataclass
class ImuObservations:
    """Observed attitudes of photos: omega, phi, kappa (rad, the convention of Photos.eo) of
    the IMU, which is the camera's attitude turned by the boresight misalignment
    (Settings.imu_boresight), with a-priori standard deviations (rad)."""

    photo: np.ndarray  # (k,) index into Photos
    angles: np.ndarray  # (k, 3)
    sigma: np.ndarray  # (k, 3)

    def __len__(self) -> int:
        return len(self.photo)


def no_gnss() -> GnssObservations:
    return GnssObservations(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))


def no_imu() -> ImuObservations:
    return ImuObservations(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))


@dataclass
class Block:
    settings: Settings
    cameras: Cameras
    photos: Photos
    image: ImagePoints
    points: GroundPoints
    source: str = ""
    notes: list[str] = field(default_factory=list)
    frame: LocalFrame | None = None  # ground coordinates are local ENU of this CRS frame
    distances: Distances = field(default_factory=no_distances)
    gnss: GnssObservations = field(default_factory=no_gnss)
    imu: ImuObservations = field(default_factory=no_imu)

    @property
    def photo_index(self) -> dict[str, int]:
        return {p: i for i, p in enumerate(self.photos.ids)}

    @property
    def point_index(self) -> dict[str, int]:
        return {p: i for i, p in enumerate(self.points.ids)}

    def rays(self) -> np.ndarray:
        """Number of photos that see each ground point, (k,)."""
        return np.bincount(self.image.point, minlength=len(self.points))

    def select_image(self, keep: np.ndarray) -> Block:
        """A copy of the block with only the image points where `keep` is True."""
        return replace(self, image=self.image.take(keep), notes=list(self.notes))

    def summary(self) -> str:
        roles = self.points.role
        return (f"{self.settings.name}: {len(self.cameras)} camera(s), {len(self.photos)} photos, "
                f"{len(self.image)} image points, {len(self.points)} ground points "
                f"({int(np.sum(roles == 'control'))} control, {int(np.sum(roles == 'check'))} "
                f"check, {int(np.sum(roles == 'tie'))} tie)"
                + (f", {len(self.distances)} distance(s)" if len(self.distances) else "")
                + (f", {len(self.gnss)} GNSS position(s)" if len(self.gnss) else "")
                + (f", {len(self.imu)} IMU attitude(s)" if len(self.imu) else ""))

