"""Reading a result folder (written by baarda.output: results.py, bundle_results.py) for the
report and `baarda check`: summary.json, the tables, checked against run.json.

The report renders what the adjustment wrote; it never recomputes w, r or MDB.  Bad or
missing files raise ProjectError naming the file, line and column.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from baarda.errors import ProjectError
from baarda.io.observations_file import numbers, read_observations, read_observations_parquet
from baarda.io.run_manifest import MANIFEST, read_json, read_manifest, verify_run
from baarda.io.table import Table
from baarda.schema import UNITS
from baarda.sections import Section


def _table_frame(path: Path, required: list[str], numeric: list[str]) -> pd.DataFrame:
    t = Table(path, required)
    df = pd.DataFrame({c: t.column(c) for c in t.header})
    for c in numeric:
        if t.has(c):
            df[c] = numbers(t, c)
    return df


@dataclass
class Results:
    """Everything the report shows, as read from an output folder."""

    folder: Path
    summary: dict
    obs: pd.DataFrame
    photos: pd.DataFrame | None = None
    points: pd.DataFrame | None = None
    cameras: dict[str, dict] = field(default_factory=dict)
    angle_unit: str | None = None
    notes: list[str] = field(default_factory=list)
    run: str | None = None  # the run id (run.json), None for folders without one
    manifest: dict = field(default_factory=dict)  # run.json: version, times, command

    @property
    def title(self) -> str:
        return str(self.summary.get("project") or self.folder.name)

    @property
    def k_w(self) -> float:
        k = self.summary.get("k_w")
        return float(k) if k is not None else float("nan")

    @property
    def sections(self) -> list[Section]:
        """The summary's sections as the adjustment wrote them (summary.json)."""
        return [Section.from_dict(s) for s in self.summary.get("sections", [])]

    def global_test_lines(self) -> list[str]:
        """The global test of every adjustment, in the words the adjustment wrote."""
        return [line for s in self.sections for line in s.lines
                if line.startswith("global test")]

    @property
    def global_test_passed(self) -> bool | None:
        """Every adjustment's global test accepted (None: no global test in the results)."""
        parts = self.summary.get("adjustments") or {"": self.summary}
        tests = [p.get("global_test") for p in parts.values() if p.get("global_test")]
        return None if not tests else all(gt.get("passed") for gt in tests)

    @property
    def units(self) -> dict[str, str]:
        """The unit of each kind's residuals in observations.csv (summary.json 'units')."""
        return {**UNITS, **(self.summary.get("units") or {})}

    @property
    def converged(self) -> bool:
        """Every adjustment of the run converged (folders without the entry count as
        converged)."""
        parts = self.summary.get("adjustments") or {"": self.summary}
        return all(p.get("converged", True) is not False for p in parts.values()
                   if isinstance(p, dict))

    def strip_of(self) -> dict[str, str]:
        """photo id -> strip label ('' when unknown)."""
        if self.photos is None or "strip" not in self.photos:
            return {}
        return dict(zip(self.photos["photo"], self.photos["strip"], strict=True))


#: the figures of summary.json (top level and each adjustment): numbers (or null)
NUMBERS = ("sigma0", "redundancy", "n_observations", "n_unknowns", "iterations", "vtpv",
           "n_check_points", "check_rms_X", "check_rms_Y", "check_rms_Z", "alpha0", "beta0",
           "delta0", "k_w", "k_tau", "sum_redundancy_numbers", "n_rejected", "n_flagged",
           "n_uncontrolled", "seconds")
#: the entries of summary.json that are containers: the JSON type each must be
CONTAINERS = {"adjustments": dict, "global_test": dict, "global_test_b_method": dict,
              "cameras": list, "sections": list, "units": dict, "notes": list,
              "rejection_log": list, "hypotheses": list, "separability": dict,
              "observation_groups": dict, "input": dict}
_JSON_TYPE = {dict: "an object", list: "an array", str: "text"}


def _is_number(v) -> bool:
    return v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))


def check_summary(summary, path: str, where: str = "") -> None:
    """The types of summary.json's entries (module docstring of output/results.py): the
    figures numbers, the containers of their kind, each adjustment, camera and section an
    object; ProjectError naming the entry otherwise."""
    if not isinstance(summary, dict):
        raise ProjectError(path, f"expected a JSON object, not {type(summary).__name__}")
    for key in NUMBERS:
        if not _is_number(summary.get(key)):
            raise ProjectError(path, f"'{where}{key}' must be a number, not "
                               f"{json.dumps(summary[key])[:40]}")
    for key, kind in CONTAINERS.items():
        v = summary.get(key)
        if v is not None and not isinstance(v, kind):
            raise ProjectError(path, f"'{where}{key}' must be {_JSON_TYPE[kind]}, not "
                               f"{type(v).__name__}")
    for key in ("global_test", "global_test_b_method"):
        for k, v in (summary.get(key) or {}).items():
            if k in ("statistic", "critical", "alpha") and not _is_number(v):
                raise ProjectError(path, f"'{where}{key}.{k}' must be a number")
    for name, part in (summary.get("adjustments") or {}).items():
        check_summary(part, path, f"adjustments.{name}.")
    for key, what in (("cameras", "camera"), ("sections", "section")):
        for i, item in enumerate(summary.get(key) or []):
            if not isinstance(item, dict):
                raise ProjectError(path, f"'{where}{key}[{i}]' must be an object (a {what})")
            if key == "sections" and not isinstance(item.get("lines", []), list):
                raise ProjectError(path, f"'{where}{key}[{i}].lines' must be an array")
    if not isinstance(summary.get("angle_unit") or "", str):
        raise ProjectError(path, f"'{where}angle_unit' must be text")


def read_results(folder: str | Path) -> Results:
    """Read summary.json, observations.csv (or observations.parquet, written by adjust
    --parquet) and (when present) photos.csv, points.csv."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ProjectError(str(folder), "not an output folder (run baarda adjust -o FOLDER)")
    sp = folder / "summary.json"
    if not sp.is_file():
        raise ProjectError(str(sp), "file not found (not a baarda output folder?)")
    run = verify_run(folder, ["summary.json", "observations.csv", "observations.parquet",
                              "photos.csv", "points.csv"])
    summary = read_json(sp)
    check_summary(summary, str(sp))
    assert isinstance(summary, dict)  # check_summary refuses anything else
    if run is None:
        raise ProjectError(str(folder / MANIFEST), "file not found: not a result folder "
                           "written by baarda (every run lists its files in it)")
    if (folder / "observations.parquet").is_file() and not (folder / "observations.csv").is_file():
        obs = read_observations_parquet(folder / "observations.parquet")
    else:
        obs = read_observations(folder / "observations.csv")
    notes: list[str] = []
    photos = points = None
    photo_block = (obs["kind"] == "image").any()  # photos, cameras and footprints apply
    if (folder / "photos.csv").is_file():
        photos = _table_frame(folder / "photos.csv", ["photo", "X0", "Y0", "Z0"],
                              ["X0", "Y0", "Z0", "omega", "phi", "kappa"])
        if "strip" not in photos:
            photos["strip"] = ""
    elif photo_block:
        notes.append("photos.csv missing: no per-strip statistics and no photo footprints")
    if (folder / "points.csv").is_file():
        points = _table_frame(folder / "points.csv", ["point", "X", "Y", "Z"],
                              ["X", "Y", "Z", "dX", "dY", "dZ", "rays"])
        if "role" not in points:
            points["role"] = "tie"
    else:
        notes.append("points.csv missing: no maps")
    cams = {c["camera"]: c for c in summary.get("cameras", []) if "camera" in c}
    unit = summary.get("angle_unit")
    if not cams and photo_block:
        notes.append("no camera data (summary.json 'cameras'): photo footprints not drawn")
    if obs["x_mm"].isna().all() and (obs["kind"] == "image").any():
        notes.append("observations.csv has no image coordinates (x_mm, y_mm): image-space "
                     "residual plots not drawn (re-run baarda adjust)")
    manifest = {k: v for k, v in read_manifest(folder / MANIFEST).items()
                if k != "files"}  # verified above: the run's own
    return Results(folder, summary, obs, photos, points, cams, unit, notes, run, manifest)
