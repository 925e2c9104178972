"""One column, one unit (issue 42): each row of a table of observations carries its unit,
lengths in the project's unit (an AICON network in mm); the run's notes in the quality
report; an input named by its files' stem has a checksum like any other."""

import hashlib
from dataclasses import replace

import numpy as np

from baarda.io.result_folder import read_results
from baarda.output.results import input_fingerprint
from baarda.report.front import length_unit, row_units
from baarda.report.quality_report import observation_parts, reliability_parts, summary_parts


def test_a_project_named_by_its_files_stem_has_a_checksum(tmp_path):
    for ext, data in (("phc", b"1 2 3\n"), ("ior", b"c 10\n"), ("eor", b"\x00\x01")):
        (tmp_path / f"example.{ext}").write_bytes(data)
    (tmp_path / "other.txt").write_bytes(b"not this project")
    h = hashlib.sha256()
    for name in ("example.eor", "example.ior", "example.phc"):  # sorted, name then bytes
        h.update(name.encode() + b"\0" + (tmp_path / name).read_bytes())
    got = input_fingerprint(tmp_path / "example")
    assert got == {"path": str(tmp_path / "example"), "files": 3, "bytes": 13,
                   "sha256": h.hexdigest()}
    assert input_fingerprint(tmp_path / "absent") is None


def test_lengths_in_the_project_unit_and_a_unit_per_row(report_case):
    res = read_results(report_case.out)
    assert length_unit(res) == ("m", 1.0)  # an aerial block: metres
    unit, f = row_units(res, np.array(["image", "control", "gnss"]))
    assert list(unit) == ["µm", "m", "m"] and list(f) == [1.0, 1.0, 1.0]
    mm = replace(res, summary={**res.summary, "notes": [
        "AICON project example: object coordinates mm -> m"]})
    assert length_unit(mm) == ("mm", 1e3)
    unit, f = row_units(mm, np.array(["image", "control"]))
    assert list(unit) == ["µm", "mm"] and list(f) == [1.0, 1e3]
    # the largest-|w| table: a unit column, MDB of a control row in mm
    part = next(p for p in observation_parts(mm) if p.kind == "table")
    assert part.title == f"the {len(part.table)} largest |w|" and len(part.table) == 25
    t = part.table
    assert {"unit", "residual", "sigma", "MDB", "external mm"} <= set(t.columns)
    o = res.obs.loc[t.index]
    want = np.where(o["kind"] == "control", 1e3, 1.0) * o["mdb"].to_numpy(float)
    assert np.allclose(t["MDB"].to_numpy(float), want, equal_nan=True)
    assert set(t["unit"]) <= {"µm", "mm"}
    rel = next(p for p in reliability_parts(mm) if p.kind == "table")
    assert list(rel.table.columns) == ["point", "largest effect mm"]
    e = res.obs[(res.obs["kind"] == "image") & np.isfinite(res.obs["external_max"])]
    ext = e.groupby("point")["external_max"].max()
    assert np.isclose(rel.table["largest effect mm"].iloc[0], 1e3 * ext.max())


def test_the_run_notes_are_in_the_quality_report(report_case):
    res = read_results(report_case.out)
    res = replace(res, summary={**res.summary, "notes": [
        "check point gcp 3 is measured on one photo only: left out"]})
    text = "\n".join(p.text for p in summary_parts(res) if p.kind == "text")
    assert "Notes of the run:\n- " in text
    assert "- check point gcp 3 is measured on one photo only: left out" in text
