"""One route per job (issue 27): each command runs what the API runs for it, with the options
resolved once; the bugs that two routes produced."""

import json
from pathlib import Path

import pandas as pd
import pytest

from baarda.cli import main

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo"
SXB = ROOT / "tests" / "data" / "dbat_sxb_aerial" / "dbat_script" / "sxb.xml"


def test_screen_before_the_bundle_keeps_the_headline_level(tmp_path):
    """`adjust --screen --alpha-global 0.2` wrote alpha 0.05: the screening route never got
    the test options."""
    out = tmp_path / "o"
    assert main(["adjust", str(DEMO), "--screen", "--alpha-global", "0.2", "--alpha0",
                 "0.002", "-o", str(out), "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["global_test"]["alpha"] == 0.2 and s["alpha0"] == 0.002


def test_baarda_screen_screens_the_block_the_bundle_sees(tmp_path):
    """`baarda screen` ran the stages on the block as read; `adjust --screen` on the block in
    its local frame with approximations.  Both are pipeline.screen_block now: the command
    writes what the API gives."""
    from baarda.output.project_files import write_project
    from baarda.pipeline import read, screen_block

    out = tmp_path / "cli"
    assert main(["screen", str(SXB), "-o", str(out), "-q"]) == 0
    res = screen_block(read(SXB))
    write_project(res.block, tmp_path / "api")
    for name in ("image_points.csv", "photos.csv", "ground_points.csv"):
        a = pd.read_csv(out / name, dtype=str)
        b = pd.read_csv(tmp_path / "api" / name, dtype=str)
        pd.testing.assert_frame_equal(a, b)
    log = pd.read_csv(out / "screening_log.csv")
    assert len(log) == len(res.log.table())


def test_plan_takes_any_input(tmp_path):
    """`plan --project` read native projects only; a DBAT script (no orientations) is
    oriented by resection first, as the bundle would."""
    if not SXB.is_file():
        pytest.skip("tests/data/dbat_sxb_aerial is missing")
    out = tmp_path / "p"
    assert main(["plan", "--project", str(SXB), "-o", str(out), "-q", "--no-plots"]) == 0
    pts = pd.read_csv(out / "plan_points.csv")
    assert len(pts) > 300


def test_one_wording_of_the_test_options():
    """--alpha0 and --beta0 come from one function (cli/common.add_test_options)."""
    import argparse

    from baarda.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = {}
    for name, p in sub.choices.items():
        for a in p._actions:
            if "--beta0" in a.option_strings:
                helps[name] = a.help
    assert {"adjust", "snoop", "screen", "models", "plan", "modified-snoop", "online",
            "evaluate"} <= set(helps)
    assert {h.split(" (")[0] for h in helps.values()} == {"power of the tests"}
    assert (ROOT / "baarda" / "cli" / "common.py").read_text().count('"--alpha0"') == 1
    cli = "".join(p.read_text() for p in (ROOT / "baarda" / "cli").glob("*.py"))
    assert cli.count('"--alpha0"') == 1
