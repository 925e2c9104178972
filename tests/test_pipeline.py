"""One program: `baarda.adjust(baarda.read(path))` does what `baarda adjust path` does, for
every supported input (native, COLMAP, BAL, DBAT, PhotoModeler, AICON, OpenSfM)."""

import json
from pathlib import Path

import numpy as np
import pytest

import baarda
import baarda.io.formats
from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.bal import BalProblem, rodrigues, rotation_vector
from baarda.output.format_files import write_bal

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
SHARED = ROOT / ".." / "shared" / "data"


def synthetic_bal(path: Path) -> Path:
    """A BAL file of 6 cameras round 60 points, projected by BAL's own model (written out
    here, independently of baarda), with 0.5 px noise."""
    rng = np.random.default_rng(7)
    ncam, npt = 6, 60
    pts = rng.uniform(-1, 1, (npt, 3)) * [2, 2, 0.5]
    cams = np.zeros((ncam, 9))
    for i in range(ncam):
        ang = 2 * np.pi * i / ncam
        centre = np.array([3 * np.cos(ang), 3 * np.sin(ang), 2.0])
        z = centre / np.linalg.norm(centre)
        x = np.cross([0, 0, 1.0], z)
        x /= np.linalg.norm(x)
        r = np.vstack([x, np.cross(z, x), z])
        cams[i, :3] = rotation_vector(r)
        cams[i, 3:6] = -r @ centre
        cams[i, 6:9] = [500 + 20 * i, -0.05, 0.01]
    cam, pt = np.repeat(np.arange(ncam), npt), np.tile(np.arange(npt), ncam)
    c = cams[cam]
    pc = np.einsum("mij,mj->mi", rodrigues(c[:, :3]), pts[pt]) + c[:, 3:6]
    q = -pc[:, :2] / pc[:, 2:3]
    n2 = np.sum(q**2, axis=1)
    xy = (c[:, 6] * (1 + c[:, 7] * n2 + c[:, 8] * n2**2))[:, None] * q
    write_bal(BalProblem(cams, pts, cam, pt, xy + rng.normal(0, 0.5, xy.shape)), path)
    return path


CASES = {
    "project": lambda tmp: ROOT / "examples" / "demo",
    "colmap": lambda tmp: DATA / "colmap_maupertuis" / "sparse",
    "bal": lambda tmp: synthetic_bal(tmp / "problem-6-60.txt.bz2"),
    "dbat": lambda tmp: DATA / "dbat_sxb_aerial" / "dbat_script" / "sxb.xml",
    "photomodeler": lambda tmp: DATA / "dbat_sxb_aerial" / "photomodeler_export" /
    "wsmart-no-orient-pmexport.txt",
    "aicon": lambda tmp: SHARED / "aicon_jaicov_closerange" / "example.phc",
    "opensfm": lambda tmp: DATA / "opensfm_berlin",
}


@pytest.mark.parametrize("fmt", list(CASES))
def test_api_and_command_line_are_one_program(fmt, tmp_path):
    path = CASES[fmt](tmp_path)
    if not path.exists():
        pytest.skip(f"{fmt} input (not in the repository) not found: {path}")
    block = baarda.read(path)
    assert baarda.io.formats.detect(path) == fmt
    res = baarda.adjust(block)
    qc = baarda.assess(res)
    assert main(["adjust", str(path), "-o", str(tmp_path / "out"), "-q"]) == 0
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["redundancy"] == res.redundancy == qc.quality.redundancy
    assert s["sigma0"] == pytest.approx(res.sigma0, rel=1e-12)
    assert s["global_test"]["statistic"] == pytest.approx(qc.quality.global_test.statistic,
                                                          rel=1e-12)
    # the same text for people, but for the computing time
    def words(sections):
        return [(title, line) for title, lines in sections for line in lines
                if not line.startswith("iterations")]
    assert words((x["title"], x["lines"]) for x in s["sections"]) == \
        words((x.title, x.lines) for x in qc.sections())
    # the block as read is not changed by the pipeline (it adjusts a prepared copy)
    again = baarda.read(path)
    assert np.array_equal(block.image.xy_mm, again.image.xy_mm)
    assert np.array_equal(block.photos.eo, again.photos.eo, equal_nan=True)


def test_dbat_redundancy_and_sigma0_are_dbats():
    """The pipeline resects DBAT's photos (no approximations in the script) and adjusts them
    to DBAT's own figures (tests/io/test_dbat.py has every value)."""
    res = baarda.adjust(baarda.read(DATA / "dbat_sxb_aerial" / "dbat_script" / "sxb.xml"))
    assert res.redundancy == 1261 and f"{res.sigma0:.4f}" == "1.1786"


def test_free_network_and_datum_choice():
    """COLMAP has no control: the pipeline holds a minimal datum (7 parameters)."""
    res = baarda.adjust(baarda.read(DATA / "colmap_maupertuis" / "sparse"))
    assert res.problem.held is not None and int(res.problem.held.sum()) == 7
    assert res.redundancy == res.n_observations - (res.problem.system.nf * 6
                                                   + res.problem.system.np * 3 - 7)


def test_check_gcp_for_any_input():
    """--check-gcp / read(check_gcp=...) turns control points of any input into check
    points: named ones, or every other one ('alternate')."""
    path = ROOT / "examples" / "demo"
    block = baarda.read(path)
    ctrl = [p for p, r in zip(block.points.ids, block.points.role, strict=True)
            if r == "control"]
    two = baarda.read(path, check_gcp=",".join(ctrl[:2]))
    assert [two.points.role[two.point_index[p]] for p in ctrl[:3]] == ["check", "check",
                                                                     "control"]
    alt = baarda.read(path, check_gcp="alternate")
    full = [p for p in ctrl if np.isfinite(block.points.xyz[block.point_index[p]]).all()]
    assert {p for p in ctrl if alt.points.role[alt.point_index[p]] == "check"} == \
        set(full[1::2])
    with pytest.raises(ProjectError, match="is not a control point"):
        baarda.read(path, check_gcp="no-such-point")
