"""The chain and the commands: baarda screen, baarda adjust --screen --snoop."""

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from baarda.cli import main
from baarda.io.project import read_project
from baarda.output.project_files import write_project
from baarda.screening.chain import ScreeningOptions, cleaned_block, screen
from baarda.simulate.aerial import FlightPlan, simulate_block

sys.path.insert(0, str(Path(__file__).parents[2] / "examples" / "lugnani"))
from lugnani_block import build  # noqa: E402


def test_clean_block_passes_unchanged():
    block, _ = build(2, blunders=False)
    res = screen(block)
    assert res.image_keep.all() and not res.control_removed
    assert not [e for e in res.log.entries if e.action == "removed"]
    assert len(res.block.image) == len(block.image)


@pytest.mark.slow
def test_control_error_located_in_stage_3_becomes_a_tie_point():
    """A strip with many control points: a 1.5 m planimetric error is located and removed."""
    plan = FlightPlan(strips=2, photos_per_strip=6, pattern=5, side_overlap=0.6,
                      control_spacing=1, relief_m=10, sigma_image_um=3.0, seed=4)
    block, _ = simulate_block(plan)
    pts = block.points
    first = screen(block, ScreeningOptions(stages=(3,)))
    assert not first.control_removed
    full = [p for p in first.control[0].points if np.isfinite(pts.sigma[p]).all()]
    bad = int(full[len(full) // 2])
    pts.xyz[bad, 0] += 1.5
    res = screen(block, ScreeningOptions(stages=(3,)))
    assert res.control_removed == [bad]
    assert res.block.points.role[bad] == "tie"
    assert np.isnan(res.block.points.xyz[bad]).all()
    assert block.points.role[bad] == "control"  # the input block is not changed
    assert res.image_keep.all()  # stage 3 alone removes no image points


def test_cleaned_block_drops_rows_and_control():
    block, _ = build(1, blunders=False)
    keep = np.ones(len(block.image), bool)
    keep[[0, 5]] = False
    out = cleaned_block(block, keep, [block.point_index["706"]])
    assert len(out.image) == len(block.image) - 2
    assert out.points.role[block.point_index["706"]] == "tie"
    assert int(np.sum(out.points.role == "control")) == 7


def test_screen_command_writes_a_cleaned_project_and_the_log(tmp_path):
    block, _ = build(1)
    proj, out = tmp_path / "lugnani", tmp_path / "screened"
    write_project(block, proj)
    before = {p.name: p.read_bytes() for p in proj.iterdir()}
    assert main(["screen", str(proj), "-o", str(out), "-q"]) == 0
    assert {p.name: p.read_bytes() for p in proj.iterdir()} == before  # input untouched
    log = pd.read_csv(out / "screening_log.csv", dtype=str)
    removed = log[(log.action == "removed") & (log.what == "image")]
    assert {("2", "609"), ("3", "609")} <= set(zip(removed.photo, removed.point, strict=True))
    cleaned = read_project(out)
    assert len(cleaned.image) == len(block.image) - len(removed)
    assert "stage 1 (photo pairs)" in (out / "screening.txt").read_text()
    assert main(["screen", str(proj), "-o", str(proj), "-q"]) == 2  # never over the input


def test_stages_option(tmp_path):
    block, _ = build(1)
    proj = tmp_path / "p"
    write_project(block, proj)
    assert main(["screen", str(proj), "-o", str(tmp_path / "o"), "--stages", "1", "-q"]) == 0
    log = pd.read_csv(tmp_path / "o" / "screening_log.csv")
    assert set(log.stage) == {1, 0} or set(log.stage) == {1}


def test_adjust_screen_snoop_in_one_go(tmp_path):
    block, truth = build(1)
    proj, out = tmp_path / "p", tmp_path / "adjusted"
    write_project(block, proj)
    assert main(["adjust", str(proj), "-o", str(out), "--screen", "--snoop", "-q"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["global_test"]["passed"]
    log = pd.read_csv(out / "screening_log.csv", dtype=str)
    assert {"1", "2", "4"} <= set(log.stage)
    points = pd.read_csv(out / "points.csv", dtype={"point": str}).set_index("point")
    d = np.array([points.loc[p, ["X", "Y", "Z"]].to_numpy(float) - truth["points"][p]
                  for p in points.index])
    assert np.sqrt(np.mean(d**2, axis=0)).max() < 0.2  # m: no blunder left in the result
