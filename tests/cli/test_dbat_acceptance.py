"""Issue 28's acceptance: DBAT's own runs of PhotoModeler exports, reproduced by the command
a user types (`baarda adjust EXPORT --control FILE ...`, run as a process from the
checkout's root), against the numbers parsed from DBAT's reports.

* camcal (camcal-dbatreport.txt, control camcal-ctrl-fixed.txt: four fixed points, DBAT's
  model 3 with nine parameters): sigma0 1.6148, redundancy 3725, the nine parameters
  within 0.01 of DBAT's standard deviation of DBAT's values and their deviations to the
  printed digits.
* SXB (wsmart-no-orient-dbatreport.txt, control sxb-control.txt, PhotoModeler's own
  frame shifted by 1e6 m against it): sigma0 1.07447, redundancy 1267.

Each runs on the copies in tests/data (DBAT licence) and, when it is beside the checkout,
on ../shared/data with the paths of the issue."""

import csv
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from baarda.block.camera_models import principal_point_to_dbat
from baarda.pipeline import read

ROOT = Path(__file__).resolve().parents[2]
SOURCES = {"tests/data": ROOT / "tests" / "data", "../shared/data": ROOT.parent / "shared" / "data"}
CAMCAL = "dbat_camcal_closerange/photomodeler_export"
SXB = "dbat_sxb_aerial"
NINE = "c,x0,y0,b1,k1,k2,k3,p1,p2"


def _source(name: str) -> str:
    if not SOURCES[name].is_dir():
        pytest.skip(f"{name} is not beside this checkout ({SOURCES[name]}): the real data "
                    "sets are read from there")
    return name


def baarda(*argv: str) -> subprocess.CompletedProcess:
    """`baarda ARGV` as a user types it, from the checkout's root."""
    return subprocess.run([sys.executable, "-m", "baarda", *argv], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


def dbat_report(path: Path) -> dict:
    text = path.read_text(encoding="utf-8")
    out = {"sigma0": re.search(r"Sigma0:\s+(\S+)", text).group(1),
           "redundancy": int(re.search(r"Redundancy\s+(\d+)", text).group(1))}
    for label, name in (("Camera Constant", "c"), ("px - principal point x", "px"),
                        ("py - principal point y", "py"), ("K1 - radial distortion 1", "k1"),
                        ("K2 - radial distortion 2", "k2"), ("K3 - radial distortion 3", "k3"),
                        ("P1 - decentering distortion 1", "p1"),
                        ("P2 - decentering distortion 2", "p2"),
                        ("as - off-unit aspect parameter", "as")):
        m = re.search(re.escape(label) + r":\s*Value:\s*(\S+)(?:\s*mm\S*)?\s*Deviation:\s*(\S+)",
                      text)
        if m:
            out[name] = (float(m.group(1)), m.group(2))
    return out


def _bundle(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text(encoding="utf-8"))["adjustments"]["bundle"]


def _unit(printed: str) -> float:
    mantissa, _, exp = printed.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** ((int(exp) if exp else 0) - decimals)


def dbat_camera(cameras_csv: Path, px: float, py: float, size_px=(2272, 1704)) -> dict:
    """baarda's camera (cameras.csv) in DBAT's convention.  The export's marks are read in
    true mm (pixel width px in x), DBAT's model 3 scales both axes by the pixel height py:
    DBAT's 1 + as = (1 + b1) px / py and its pp x (from the centre) = x0 py / px; pp from
    the upper-left corner, y down (block/camera_models.principal_point_to_dbat)."""
    rows = {r["parameter"]: r for r in csv.DictReader(cameras_csv.open(encoding="utf-8"))}
    v = {k: float(r["value"]) for k, r in rows.items()}
    s = {k: float(r["sigma"]) for k, r in rows.items() if r["sigma"]}
    ratio = px / py
    fmt = np.array([[size_px[0] * py, size_px[1] * py]])
    pp = principal_point_to_dbat(np.array([[v["x0"] / ratio, v["y0"]]]), [0.0], fmt, "dbat3")[0]
    out = {name: (v[name], s[name]) for name in ("c", "k1", "k2", "k3", "p1", "p2")}
    out["px"] = (pp[0], s["x0"] / ratio)
    out["py"] = (pp[1], s["y0"])
    out["as"] = ((1 + v["b1"]) * ratio - 1, s["b1"] * ratio)
    return out


@pytest.mark.parametrize("source", list(SOURCES))
def test_camcal_photomodeler_export_with_dbat_control(source, tmp_path):
    root = _source(source)
    out = tmp_path / "OUT"
    run = baarda("adjust", f"{root}/{CAMCAL}/camcal-pmexport.txt", "--control",
                 f"{root}/{CAMCAL}/camcal-ctrl-fixed.txt", "--camera-model", "dbat3",
                 "--calibrate", NINE, "-o", str(out))
    assert run.returncode == 0, run.stderr
    ref = dbat_report(SOURCES[root] / CAMCAL / "camcal-dbatreport.txt")
    got = _bundle(out)
    assert f"{got['sigma0']:.4f}" == ref["sigma0"] == "1.6148"
    block = read(ROOT / root / CAMCAL / "camcal-pmexport.txt",
                 control=ROOT / root / CAMCAL / "camcal-ctrl-fixed.txt")
    ctrl = block.points.role == "control"
    assert ctrl.sum() == 4 and np.all(block.points.sigma[ctrl] == 0)  # 4 fixed points
    assert got["redundancy"] == ref["redundancy"] == 3725
    cam = dbat_camera(out / "cameras.csv", 7.25319 / 2272, 5.43764 / 1704)
    assert set(ref) - {"sigma0", "redundancy"} == set(cam)
    for name, (value, dev) in cam.items():
        ref_value, ref_dev = ref[name]
        assert abs(value - ref_value) <= 0.01 * float(ref_dev), (name, value, ref_value)
        assert abs(dev - float(ref_dev)) <= 0.5 * _unit(ref_dev), (name, dev, ref_dev)


@pytest.mark.parametrize("source", list(SOURCES))
def test_sxb_photomodeler_export_with_dbat_control(source, tmp_path):
    root = _source(source)
    out = tmp_path / "OUT"
    run = baarda("adjust", f"{root}/{SXB}/photomodeler_export/wsmart-no-orient-pmexport.txt",
                 "--control", f"{root}/{SXB}/dbat_script/reference/sxb-control.txt",
                 "-o", str(out))
    assert run.returncode == 0, run.stderr
    ref = dbat_report(ROOT / "tests" / "data" / SXB / "photomodeler_export" /
                      "wsmart-no-orient-dbatreport.txt")
    got = _bundle(out)
    assert f"{got['sigma0']:.5f}" == ref["sigma0"] == "1.07447"
    block = read(ROOT / root / SXB / "photomodeler_export" / "wsmart-no-orient-pmexport.txt",
                 control=ROOT / root / SXB / "dbat_script" / "reference" / "sxb-control.txt")
    ctrl = block.points.role == "control"
    assert ctrl.sum() == 16 and np.allclose(block.points.sigma[ctrl], [0.02, 0.02, 0.04])
    # issue 41: the reader's note on PhotoModeler's own control is replaced, not printed
    assert not any("PhotoModeler lists" in n for n in block.notes)
    assert "PhotoModeler lists" not in run.stdout
    assert any("PhotoModeler lists" in n for n in read(
        ROOT / root / SXB / "photomodeler_export" / "wsmart-no-orient-pmexport.txt").notes)
    assert got["redundancy"] == ref["redundancy"] == 1267
    assert "another frame" in run.stdout  # PhotoModeler's shifted frame: resected
