"""The observation kinds, one `Kind` each: what every floor knows of a kind of observation.

A kind's `name` is the word observations.csv writes in its `kind` column (and summary.json
in its `units`); every other floor looks the kind up here (`KINDS[name]`, `kind_of`)
instead of spelling the word and deciding what it means itself:

* `components`: the labels of its components, in the order of its rows;
* `unit`, `scale`: the unit of its residuals, sigmas and MDBs in files and reports, and the
  factor from the computation's unit (mm of the image, m, rad) to it; an `angular` kind
  (IMU attitudes) is shown in thousandths of the project's angle unit (`ANGLE_UNITS`:
  mgon, mdeg or mrad), `shown(angle_unit)`;
* `frame`: what a row is tied to besides its point: "photo", "model" or "" (control and
  distances: the point alone); `named_point`: whether its rows name a point (GNSS and IMU
  rows name their photo only);
* `by_axis`: its X, Y and Z are variance-component groups of their own (control, GNSS;
  quality/variance_components.py pools them when too weak alone);
* `words`: how the summaries name it ("GNSS"), `title`: what the reports call its rows.

Adding a kind: one entry here, its rows (bundle/observation_kinds.py), its reader field and
its data class.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# thousandths of the project's angle unit: the unit of an angular kind's residuals
ANGLE_UNITS: dict[str, tuple[float, str]] = {
    "gon": (200e3 / math.pi, "mgon"), "deg": (180e3 / math.pi, "mdeg"),
    "rad": (1e3, "mrad")}


@dataclass(frozen=True)
class Kind:
    """One kind of observation (module docstring)."""

    name: str
    components: tuple[str, ...]
    unit: str
    scale: float
    frame: str = ""
    named_point: bool = True
    by_axis: bool = False
    angular: bool = False
    words: str = ""
    title: str = ""

    def shown(self, angle_unit: str = "rad") -> tuple[float, str]:
        """(factor from the computation's unit, unit) of its residuals, sigmas and MDBs in
        files and reports; an angular kind in thousandths of `angle_unit`."""
        if self.angular:
            return ANGLE_UNITS.get(angle_unit, ANGLE_UNITS["rad"])
        return self.scale, self.unit

    @property
    def on_photo(self) -> bool:
        """Its rows belong to a photo (image points, GNSS positions, IMU attitudes)."""
        return self.frame == "photo"


IMAGE = Kind("image", ("x", "y"), "µm", 1e3, frame="photo", words="image",
             title="image coordinates")
MODEL = Kind("model", ("x", "y", "z"), "µm", 1e3, frame="model", words="model",
             title="model coordinates")
CONTROL = Kind("control", ("X", "Y", "Z"), "m", 1.0, by_axis=True, words="control",
               title="control coordinates")
DISTANCE = Kind("distance", ("d",), "m", 1.0, words="distances", title="distances")
GNSS = Kind("gnss", ("X", "Y", "Z"), "m", 1.0, frame="photo", named_point=False,
            by_axis=True, words="GNSS", title="GNSS positions of the projection centres")
IMU = Kind("imu", ("omega", "phi", "kappa"), "mrad", 1e3, frame="photo",
           named_point=False, angular=True, words="IMU", title="IMU attitudes of the photos")

KINDS: dict[str, Kind] = {k.name: k for k in (IMAGE, MODEL, CONTROL, DISTANCE, GNSS, IMU)}
OTHER = Kind("", (), "", 1.0)  # an unknown kind: shown as computed, without a unit
EXTERIOR = (GNSS, IMU)  # the photos' orientations observed directly (GNSS/IMU)
EXTERIOR_NAMES = tuple(k.name for k in EXTERIOR)  # their rows name a photo, no point
BY_AXIS = tuple(k.name for k in KINDS.values() if k.by_axis)


def kind_of(name: str) -> Kind:
    """The Kind named `name` (OTHER for a word no kind has)."""
    return KINDS.get(str(name), OTHER)


def units(angle_unit: str = "rad") -> dict[str, tuple[float, str]]:
    """kind -> (factor, unit) of every kind, angular kinds in thousandths of `angle_unit`."""
    return {name: k.shown(angle_unit) for name, k in KINDS.items()}


def unit_names(angle_unit: str = "rad") -> dict[str, str]:
    """kind -> the unit of its residuals in files (summary.json's `units`)."""
    return {name: u for name, (_, u) in units(angle_unit).items()}
