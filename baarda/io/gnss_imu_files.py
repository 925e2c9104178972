"""GNSS and IMU observations of a native project: gnss.csv, imu.csv and the [gnss], [imu]
tables of project.toml (docs/format.md).  Both files are optional."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import (
    GNSS_OFFSETS,
    IMU_BORESIGHT,
    GnssObservations,
    ImuObservations,
    Settings,
    no_gnss,
    no_imu,
)
from baarda.block.rotation import angle_to_rad
from baarda.errors import ProjectError
from baarda.io.table import Table
from baarda.io.text_files import ENCODING
from baarda.kinds import GNSS, IMU

DEFAULT_GNSS_SIGMA_M = (0.05, 0.05, 0.05)
DEFAULT_IMU_SIGMA_DEG = 0.005


def gnss_imu_settings(doc: dict, path: Path, s: Settings) -> dict:
    """Settings fields from [gnss] (lever_arm, offsets, drift) and [imu] (boresight), and
    the default sigmas from [sigma] gnss_m (m, one or [X, Y, Z]) and imu (angle_unit)."""
    from baarda.io.project_toml import toml_table

    g, i, sig = toml_table(doc, GNSS.name, path), toml_table(doc, IMU.name, path), \
        toml_table(doc, "sigma", path)
    try:
        lever = [float(v) for v in g.get("lever_arm", [0.0, 0.0, 0.0])]
        gs = sig.get(f"{GNSS.name}_m", list(DEFAULT_GNSS_SIGMA_M))
        gs = [float(gs)] * 3 if np.isscalar(gs) else [float(v) for v in gs]  # type: ignore[arg-type]
        imu_default = float(angle_to_rad(np.array(DEFAULT_IMU_SIGMA_DEG), "deg"))
        isig = (float(angle_to_rad(np.array(float(sig[IMU.name])), s.angle_unit))
                if IMU.name in sig else imu_default)
    except (TypeError, ValueError, OverflowError) as e:
        raise ProjectError(str(path), f"a [gnss] or [sigma] setting is not a number: {e}",
                           column=GNSS.name) from None
    if len(lever) != 3 or not np.isfinite(lever).all():
        raise ProjectError(str(path), "gnss.lever_arm must be [dx, dy, dz] in m (camera frame)",
                           column="gnss.lever_arm")
    if len(gs) != 3 or not all(np.isfinite(v) and v > 0 for v in gs) or \
            not (np.isfinite(isig) and isig > 0):
        raise ProjectError(str(path), "sigma.gnss_m and sigma.imu must be positive",
                           column="sigma")
    offsets = g.get("offsets", "none")
    if offsets not in GNSS_OFFSETS:
        raise ProjectError(str(path), f"gnss.offsets '{offsets}' is not one of "
                           f"{', '.join(GNSS_OFFSETS)}", column="gnss.offsets")
    drift = g.get("drift", False)
    if not isinstance(drift, bool):
        raise ProjectError(str(path), "gnss.drift must be true or false", column="gnss.drift")
    bore = i.get("boresight", "fixed")
    if bore not in IMU_BORESIGHT:
        raise ProjectError(str(path), f"imu.boresight '{bore}' is not one of "
                           f"{', '.join(IMU_BORESIGHT)}", column="imu.boresight")
    return dict(gnss_lever_arm=tuple(lever), gnss_offsets=offsets, gnss_drift=drift,
                imu_boresight=bore, gnss_sigma=tuple(gs), imu_sigma=isig)


def _sigmas(t: Table, names: list[str], default: np.ndarray) -> np.ndarray:
    """(k, 3) sigmas from the columns `names` (all or none; empty: the default)."""
    have = [t.has(n) for n in names]
    if any(have) and not all(have):
        raise ProjectError(t.path, f"give all three columns {', '.join(names)} or none")
    if not all(have):
        return np.tile(default, (len(t), 1))
    sig = np.column_stack([t.numbers(n, allow_empty=True) for n in names])
    bad = np.argwhere(np.isfinite(sig) & ~(sig > 0))
    if len(bad):
        r, c = bad[0]
        raise ProjectError(t.path, "standard deviation must be positive", int(t.lines[r]),
                           names[c])
    return np.where(np.isfinite(sig), sig, default)


def _photos(t: Table, photo_ids: list[str]) -> np.ndarray:
    photo = t.lookup("photo", {p: i for i, p in enumerate(photo_ids)}, "photo")
    order = np.argsort(photo, kind="stable")
    dup = np.flatnonzero(np.diff(photo[order]) == 0)
    if len(dup):
        i = int(order[dup[0] + 1])
        raise ProjectError(t.path, f"photo '{photo_ids[photo[i]]}' twice (first on line "
                           f"{int(t.lines[order[dup[0]]])})", int(t.lines[i]), "photo")
    return photo


def read_gnss(path: Path, photo_ids: list[str], sigma_m, encoding: str = ENCODING
              ) -> GnssObservations:
    """gnss.csv: `photo, X, Y, Z` (m, the antenna in the ground CRS) and optionally
    `sigma_X, sigma_Y, sigma_Z` (m; empty: [sigma] gnss_m) and `time` (s)."""
    if not path.is_file():
        return no_gnss()
    t = Table(path, ["photo", "X", "Y", "Z"], encoding)
    photo = _photos(t, photo_ids)
    xyz = np.column_stack([t.numbers(c) for c in "XYZ"])
    sig = _sigmas(t, ["sigma_X", "sigma_Y", "sigma_Z"], np.asarray(sigma_m, float))
    time = t.numbers("time", allow_empty=True) if t.has("time") else None
    return GnssObservations(photo, xyz, sig, time)


def read_imu(path: Path, photo_ids: list[str], unit: str, sigma_rad: float,
             encoding: str = ENCODING) -> ImuObservations:
    """imu.csv: `photo, omega, phi, kappa` (the project's angle_unit) and optionally
    `sigma_omega, sigma_phi, sigma_kappa` (angle_unit; empty: [sigma] imu)."""
    if not path.is_file():
        return no_imu()
    t = Table(path, ["photo", "omega", "phi", "kappa"], encoding)
    photo = _photos(t, photo_ids)
    ang = angle_to_rad(np.column_stack([t.numbers(c) for c in ("omega", "phi", "kappa")]),
                       unit)
    names = ["sigma_omega", "sigma_phi", "sigma_kappa"]
    sig = _sigmas(t, names, np.full(3, np.nan))
    sig = np.where(np.isfinite(sig), angle_to_rad(np.where(np.isfinite(sig), sig, 1.0), unit),
                   sigma_rad)
    return ImuObservations(photo, ang, sig)
