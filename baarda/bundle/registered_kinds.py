"""The observation kinds every bundle problem has, in the order of their rows
(bundle/observation_kinds.py): a new built-in kind is one module and one entry here; a
problem's own kinds (`BundleProblem(kinds=...)`) follow them."""

from __future__ import annotations

import numpy as np

from baarda.bundle.kind_control import BorderControl
from baarda.bundle.kind_distance import Distances
from baarda.bundle.kind_gnss_imu import GnssImuKind
from baarda.bundle.kind_image import BorderImages
from baarda.bundle.observation_kinds import ObservationKind


def registered_kinds(usable: np.ndarray) -> tuple[ObservationKind, ...]:
    """The built-in kinds of a problem whose adjusted points are `usable` (block indices):
    the image points and control of border points, distances, GNSS/IMU."""
    return (BorderImages(), BorderControl(), Distances(usable), GnssImuKind())
