"""A simulated block with injected blunders, snooped, written and reported (once)."""

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import pytest

from baarda.io.result_folder import read_results
from baarda.output.bundle_results import write_results
from baarda.output.project_files import write_project
from baarda.pipeline import snoop
from baarda.report.html_report import html_report
from baarda.report.text_report import ReportOptions
from baarda.simulate.aerial import FlightPlan, simulate_block

# helper modules of these tests (salsig.py, htmlrows.py); pytest runs with importlib mode
sys.path.insert(0, str(Path(__file__).parent))


@dataclass
class Case:
    project: Path
    out: Path
    html_path: Path
    html: str
    truth: dict
    obs: pd.DataFrame  # observations.csv as written


@pytest.fixture(scope="session")
def report_case(tmp_path_factory) -> Case:
    root = tmp_path_factory.mktemp("report")
    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=5, blunders=5,
                                             check_points=2, relief_m=30.0, seed=1))
    write_project(block, root / "project")
    qc = snoop(block)
    write_results(root / "out", qc)
    res = read_results(root / "out")
    text = html_report(res, ReportOptions(vector_photos=15))
    (root / "report.html").write_text(text, encoding="utf-8")
    obs = pd.read_csv(root / "out" / "observations.csv", dtype={"photo": str, "point": str},
                      keep_default_na=False, na_values=[""])
    return Case(root / "project", root / "out", root / "report.html", text,
                json.loads(json.dumps(truth, default=float)), obs)
