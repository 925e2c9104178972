"""DBAT's camera calibration project adjusts as DBAT did (issue 13 acceptance): the script
estimates the interior orientation (DBAT's model 3 with aspect, K1..K3, P1, P2), the four
control points are fixed; sigma0, redundancy and every camera parameter against DBAT's
report (result/report.txt)."""

import re
from pathlib import Path

import numpy as np
import pytest

from baarda.block.camera_models import principal_point_to_dbat
from baarda.cli import main
from baarda.pipeline import adjust, read

DATA = Path(__file__).resolve().parents[1] / "data" / "dbat_camcal_closerange" / "dbat_script"
SCRIPT = DATA / "camcaldemo.xml"


def report_parameters() -> dict[str, tuple[float, float]]:
    """(value, deviation) of each camera parameter in DBAT's report."""
    text = (DATA / "result" / "report.txt").read_text(encoding="utf-8")
    out = {}
    for label, name in (("Camera Constant", "c"), ("px - principal point x", "px"),
                        ("py - principal point y", "py"), ("K1 - radial distortion 1", "k1"),
                        ("K2 - radial distortion 2", "k2"), ("K3 - radial distortion 3", "k3"),
                        ("P1 - decentering distortion 1", "p1"),
                        ("P2 - decentering distortion 2", "p2"),
                        ("as - off-unit aspect parameter", "b1")):
        m = re.search(re.escape(label) + r":\s*Value:\s*(\S+).*?\s*Deviation:\s*(\S+)", text,
                      flags=re.S)
        out[name] = (float(m.group(1)), float(m.group(2)))
    return out


@pytest.fixture(scope="module")
def result():
    return adjust(read(SCRIPT))


def test_sigma0_redundancy_and_counts(result):
    assert f"{result.sigma0:.4f}" == "1.6148"  # DBAT: Sigma0 1.6148
    assert result.redundancy == 3725  # DBAT: Redundancy 3725
    assert result.n_observations == 4148 and result.n_unknowns == 423  # 9 IO, 126 EO, 288 OP


def test_camera_within_two_sigma_of_dbat(result):
    ref = report_parameters()
    table = {r["parameter"]: r for r in result.camera_table()}
    assert {p for p, r in table.items() if r["estimated"]} == \
        {"c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "b1"}
    cam = result.block.cameras
    iw, ih = 2272, 1704
    py = 5.43764 / ih
    pp = principal_point_to_dbat(np.array([[table["x0"]["value"], table["y0"]["value"]]]),
                                 [table["b1"]["value"]], np.array([[iw * py, ih * py]]),
                                 "dbat3")[0]
    got = {"c": table["c"]["value"], "px": pp[0], "py": pp[1],
           **{k: table[k]["value"] for k in ("k1", "k2", "k3", "p1", "p2", "b1")}}
    sigma = {"c": table["c"]["sigma"], "px": table["x0"]["sigma"], "py": table["y0"]["sigma"],
             **{k: table[k]["sigma"] for k in ("k1", "k2", "k3", "p1", "p2", "b1")}}
    for name, (value, dev) in ref.items():
        assert abs(got[name] - value) <= 2 * dev, (name, got[name], value, dev)
        assert np.isclose(sigma[name], dev, rtol=0.05), (name, sigma[name], dev)
    assert cam.model[0] == "dbat3"


def test_fixed_control_is_fixed_and_not_tested(result, tmp_path):
    pb = result.problem
    assert pb.held_points.sum() == 12 and len(pb.layout.ctrl_sel) == 0
    assert main(["adjust", str(SCRIPT), "-o", str(tmp_path / "o"), "-q"]) == 0
    import pandas as pd

    obs = pd.read_csv(tmp_path / "o" / "observations.csv")
    assert not (obs["kind"] == "control").any()  # fixed: not an observation, never tested


def test_calibrated_camera_from_the_command_line(tmp_path):
    """`--camera result/c4040z.xml --calibrate none`: DBAT's calibrated camera held fixed,
    redundancy 3734 (3725 + the 9 parameters) and sqrt(vTPv) 98.556 as DBAT's (98.542 when
    the fixed control was entered with sigma 1e-6 m, realdata.md); a camera file for input
    that is not a DBAT script is a clear error."""
    import json

    cam = DATA / "result" / "c4040z.xml"
    out = tmp_path / "out"
    assert main(["adjust", str(SCRIPT), "--camera", str(cam), "--calibrate", "none",
                 "-o", str(out), "-q"]) == 0
    part = json.loads((out / "summary.json").read_text())["adjustments"]["bundle"]
    assert part["redundancy"] == 3734 and abs(np.sqrt(part["vtpv"]) - 98.556) < 5e-4
    demo = Path(__file__).resolve().parents[2] / "examples" / "demo"
    assert main(["adjust", str(demo), "--camera", str(cam), "-o", str(tmp_path / "x")]) == 2
