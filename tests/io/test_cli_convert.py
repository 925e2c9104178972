"""`baarda convert` and `baarda adjust` on foreign inputs (read_any routing)."""

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.block.crs import LocalFrame
from baarda.block.photo_block import Photos
from baarda.cli import main
from baarda.io.bal import bal_to_block
from baarda.io.formats import detect, read_any
from baarda.io.project import read_project
from baarda.output.format_files import write_bal
from baarda.output.project_files import write_project
from baarda.simulate.aerial import FlightPlan, simulate_block

DATA = Path(__file__).resolve().parents[1] / "data"
SXB = DATA / "dbat_sxb_aerial" / "dbat_script" / "sxb.xml"
PM = DATA / "dbat_sxb_aerial" / "photomodeler_export" / "wsmart-no-orient-pmexport.txt"
COLMAP = DATA / "colmap_maupertuis" / "sparse"
sys.path.insert(0, str(Path(__file__).parent))


def test_detect():
    assert detect(SXB) == "dbat"
    assert detect(PM) == "photomodeler"
    assert detect(COLMAP) == "colmap" and detect(COLMAP.parent) == "colmap"


def test_convert_dbat_then_adjust_reproduces_dbat(tmp_path):
    assert main(["convert", str(SXB), "-o", str(tmp_path / "p"), "-q"]) == 0
    assert main(["adjust", str(tmp_path / "p"), "-o", str(tmp_path / "r"), "-q"]) == 0
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["redundancy"] == 1261 and f"{s['sigma0']:.4f}" == "1.1786"
    # adjusting the DBAT script directly gives the same
    assert main(["adjust", str(SXB), "-o", str(tmp_path / "r2"), "-q"]) == 0
    s2 = json.loads((tmp_path / "r2" / "summary.json").read_text())
    assert np.isclose(s2["sigma0"], s["sigma0"], rtol=1e-10)


def test_adjust_colmap_free_network(tmp_path):
    assert main(["adjust", str(COLMAP), "-o", str(tmp_path / "r"), "-q"]) == 0
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    # 3350 image points, 4 photos, 1039 points, datum 7: u = 24 + 3117 - 7
    assert s["n_observations"] == 6700 and s["n_unknowns"] == 3134
    assert np.isclose(s["sum_redundancy_numbers"], s["redundancy"], atol=1e-6)
    obs = pd.read_csv(tmp_path / "r" / "observations.csv")
    assert len(obs) == 6700 and obs["redundancy"].between(0, 1).all()


def test_bal_with_lens_model_through_native_project(tmp_path):
    from bal_reference import _synthetic

    p = _synthetic(seed=4)
    write_bal(p, tmp_path / "p.txt.bz2")
    assert main(["convert", str(tmp_path / "p.txt.bz2"), "-o", str(tmp_path / "proj"),
                 "-q"]) == 0
    back = read_project(tmp_path / "proj")
    ref = bal_to_block(p)
    assert list(back.cameras.model) == list(ref.cameras.model) == ["brown_forward"] * 6
    from baarda.block.camera import coefficients

    for i in range(6):
        assert np.array_equal(coefficients(back.cameras, i), coefficients(ref.cameras, i))
    assert main(["adjust", str(tmp_path / "proj"), "-o", str(tmp_path / "r1"), "-q"]) == 0
    assert main(["adjust", str(tmp_path / "p.txt.bz2"), "-o", str(tmp_path / "r2"),
                 "-q"]) == 0
    s1 = json.loads((tmp_path / "r1" / "summary.json").read_text())
    s2 = json.loads((tmp_path / "r2" / "summary.json").read_text())
    assert np.isclose(s1["sigma0"], s2["sigma0"], rtol=1e-8) and 0.4 < s1["sigma0"] < 0.6


def test_adjust_in_a_crs_writes_crs_results(tmp_path):
    plan = FlightPlan(strips=2, photos_per_strip=3, relief_m=20.0, seed=8)
    local, truth = simulate_block(plan)
    frame = LocalFrame("EPSG:32632", np.array([300000.0, 5380000.0, 0.0]))
    block = replace(local, points=replace(local.points, xyz=frame.from_local(local.points.xyz)),
                    photos=Photos(local.photos.ids, local.photos.camera, local.photos.strip,
                                  frame.eo_from_local(local.photos.eo)))
    write_project(block, tmp_path / "p")
    assert main(["adjust", str(tmp_path / "p"), "-o", str(tmp_path / "r"), "-q",
                 "--crs", "EPSG:32632"]) == 0
    ph = pd.read_csv(tmp_path / "r" / "photos.csv")
    eo = np.array([[truth["photos"][p][k] for k in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
                   for p in local.photos.ids])
    true_eo = frame.eo_from_local(eo)
    # adjusted projection centres near the truth in UTM (noise: decimetres), not local
    assert np.abs(ph[["X0", "Y0", "Z0"]].to_numpy() - true_eo[:, :3]).max() < 1.0
    loc = pd.read_csv(tmp_path / "r" / "photos_local.csv")
    assert np.abs(loc["X0"].to_numpy()).max() < 1e5


def test_unrecognised_input_is_an_error(tmp_path, capsys):
    (tmp_path / "x.txt").write_text("hello\n")
    assert main(["convert", str(tmp_path / "x.txt"), "-o", str(tmp_path / "p")]) == 2
    assert "format not recognised" in capsys.readouterr().err
    assert not (tmp_path / "p").exists()


def test_read_any_options():
    b = read_any(COLMAP, pixel_mm=0.005, sigma_px=0.5)
    assert np.isclose(b.cameras.focal_mm[0], 1847.53 * 0.005)
    assert np.allclose(b.image.sigma_mm, 0.0025)


def test_pixel_size_and_image_sigma_must_be_positive(tmp_path, capsys):
    from bal_reference import _synthetic

    write_bal(_synthetic(seed=4), tmp_path / "p.txt")
    for src in (COLMAP, tmp_path / "p.txt", DATA / "opensfm_berlin"):
        for option in (["--pixel-mm", "0"], ["--sigma-px", "-1"]):
            assert main(["convert", str(src), "-o", str(tmp_path / "out"), "-q",
                         *option]) == 2
            assert f"argument {option[0]}: a number > 0" in capsys.readouterr().err
            assert not (tmp_path / "out").exists()
