"""`baarda plan` and `baarda modified-snoop` write their outputs; errors are clear."""

import html

import numpy as np
import pandas as pd
import pytest

from baarda.cli import main
from baarda.output.project_files import write_project
from baarda.simulate.aerial import FlightPlan, simulate_block


def test_plan_flight(tmp_path, capsys):
    out = tmp_path / "plan"
    rc = main(["plan", "-o", str(out), "--strips", "3", "--photos", "4", "--side-overlap",
               "0.6", "--stereo", "--focal", "150", "--bridging", "1.5", "--twin-control",
               "--derive-table", str(tmp_path / "table.csv"), "-q"])
    assert rc == 0
    for f in ("plan_report.txt", "plan_observations.csv", "plan_classes.csv",
              "plan_points.csv", "plan_photos.csv", "plan_maps.png"):
        assert (out / f).is_file()
    obs = pd.read_csv(out / "plan_observations.csv")
    text = (out / "plan_report.txt").read_text()
    red = int(text.split("redundancy ")[1].split(";")[0])
    assert obs["redundancy"].sum() == pytest.approx(red, abs=1e-4)
    img = obs[obs["kind"] == "image"]
    mdb = 4.132 * img["sigma"] / np.sqrt(img["redundancy"])  # delta0(0.001, 0.80) = 4.132
    ok = img["redundancy"] > 1e-3
    assert np.allclose(img.loc[ok, "mdb"], mdb[ok], rtol=1e-3)
    assert "Advice" in text and "twin" in (tmp_path / "table.csv").read_text()
    # the HTML report in the reports' look, its advice table = plan_advice.csv
    advice = pd.read_csv(out / "plan_advice.csv", keep_default_na=False)
    page = (out / "plan_report.html").read_text(encoding="utf-8")
    assert '<section id="advice">' in page and '<section id="maps">' in page
    assert page.count("<tr>") >= len(advice) + 1
    for finding in advice["finding"]:
        assert html.escape(finding) in page
    # the derived table is usable by modified-snoop
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=4, side_overlap=0.6,
                                         stereo=True, focal_mm=150, blunders=2, seed=2))
    write_project(block, tmp_path / "proj")
    rc = main(["modified-snoop", str(tmp_path / "proj"), "-o", str(tmp_path / "ms"), "--table",
               str(tmp_path / "table.csv"), "-q"])
    assert rc == 0
    ms = pd.read_csv(tmp_path / "ms" / "modified_snooping.csv")
    assert ms["exact"].sum() > 0 and "exact qvv" in (tmp_path / "ms" /
                                                      "modified_snooping.txt").read_text()


def test_plan_project_and_errors(tmp_path, capsys):
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=4, side_overlap=0.6,
                                         stereo=True, relief_m=20, seed=1))
    write_project(block, tmp_path / "proj")
    assert main(["plan", "--project", str(tmp_path / "proj"), "-o", str(tmp_path / "o"),
                 "--no-plots", "-q"]) == 0
    assert (tmp_path / "o" / "plan_report.txt").is_file()
    # never into the input folder
    assert main(["plan", "--project", str(tmp_path / "proj"), "-o", str(tmp_path / "proj"),
                 "-q"]) == 2
    # a hinged design: flat terrain, one row of ties between strips, no height control there
    assert main(["plan", "-o", str(tmp_path / "h"), "--strips", "3", "--photos", "5",
                 "--bridging-y", "2", "-q"]) == 2
    assert "hinge" in capsys.readouterr().err
