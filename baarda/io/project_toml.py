"""project.toml: the document read (its angle unit checked), its tables and the keys each
accepts (docs/format.md), for the native project (io/project.py), the model project
(io/model_project.py) and the GNSS/IMU settings (io/gnss_imu_files.py)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from baarda.block.rotation import ANGLE_FACTORS
from baarda.errors import ProjectError
from baarda.io.text_files import ENCODING, decode_text, file_bytes
from baarda.kinds import GNSS, IMU


def load_toml(path: Path, default_unit: str = "gon",
              encoding: str = ENCODING) -> tuple[dict, str]:
    """project.toml as a dict and its checked angle unit; errors name the file."""
    data = file_bytes(path, "file not found (a project folder needs project.toml)")
    try:
        doc = tomllib.loads(decode_text(data, str(path), encoding))
    except tomllib.TOMLDecodeError as e:
        raise ProjectError(str(path), f"not valid TOML: {e}") from None
    unit = str(doc.get("angle_unit", default_unit))
    if unit not in ANGLE_FACTORS:
        raise ProjectError(str(path), f"angle_unit '{unit}' is not one of gon, deg, rad",
                           column="angle_unit")
    return doc, unit


def toml_table(doc: dict, key: str, path: Path) -> dict:
    """The table `key` of a project.toml document ({} when absent); ProjectError when the
    key holds a value that is not a table."""
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise ProjectError(str(path), f"'{key}' must be a table ([{key}] followed by its "
                           f"keys), not a {type(value).__name__}", column=key)
    return value


def positive_settings(path: Path, values: dict[str, float],
                      most: float = float("inf")) -> None:
    """ProjectError naming the first setting that is not a finite positive number (at most
    `most`)."""
    for name, v in values.items():
        if not (np.isfinite(v) and v > 0):
            raise ProjectError(str(path), f"{name} = {v!r}: standard deviations and thresholds "
                               "must be finite positive numbers", column=name)
        if v > most:
            raise ProjectError(str(path), f"{name} = {v!r}: at most {most:g}", column=name)


# the keys project.toml accepts, by table ("": its top); [calibration] also takes a table
# per camera id (docs/format.md); the tables and sigmas of an observation kind by its name
KEYS = {"": ("name", "angle_unit", "image_unit", "crs", "datum", "sigma", "tests",
             "calibration", GNSS.name, IMU.name),
        "sigma": ("image_um", "control_m", "distance_m", f"{GNSS.name}_m", IMU.name),
        "tests": ("alpha0", "beta0", "alpha_global"),
        GNSS.name: ("lever_arm", "offsets", "drift"),
        IMU.name: ("boresight",),
        "calibration": ("free", "group")}
HINTS = {"calibration.calibrate": " (the command line's --calibrate is `free` here)",
         "calibration.fixed": " (list the parameters to estimate in `free`; the others are "
                              "held)"}


def check_keys(table: dict, path: Path, name: str = "", more: tuple[str, ...] = (),
               also: str = "", keys: dict[str, tuple[str, ...]] = KEYS) -> None:
    """ProjectError naming the first key of `table` (project.toml's [name], "": its top)
    that is not one of keys[name] + `more`, the file and the keys it accepts (`also`: words
    for `more` in the message; `keys`: a model project's MODEL_KEYS)."""
    for key in table:
        if key in keys[name] or key in more:
            continue
        dotted = f"{name}.{key}" if name else key
        where = f"[{name}]" if name else "project.toml's top level"
        raise ProjectError(str(path), f"unknown key '{dotted}'{HINTS.get(dotted, '')}: "
                           f"{where} accepts {', '.join(keys[name])}{also}", column=dotted)


def given_keys(doc: dict) -> frozenset[str]:
    """The dotted keys of the settings a project.toml gives ("tests.alpha0", "datum")."""
    return frozenset([k for k, v in doc.items() if not isinstance(v, dict)] +
                     [f"{k}.{kk}" for k, v in doc.items() if isinstance(v, dict) for kk in v])
