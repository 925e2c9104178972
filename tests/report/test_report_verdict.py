"""The quality check of a whole run (issue 42): a clean, well-designed block passes."""

from baarda.output.bundle_results import write_results
from baarda.pipeline import snoop
from baarda.report.front import folder_quality_check
from baarda.simulate.aerial import FlightPlan, simulate_block


def test_a_clean_block_with_60_percent_side_overlap_passes(tmp_path):
    block, _ = simulate_block(FlightPlan(strips=4, photos_per_strip=8, side_overlap=0.6,
                                         check_points=5, blunders=0, seed=1))
    write_results(tmp_path / "out", snoop(block))
    v = folder_quality_check(tmp_path / "out", 5.0)
    assert v.headline == "PASS: every check of this run passed", v.lines()
    rows = {r.key: r for r in v.rows}
    # two-ray points at the block's ends: stated with the remedy, not a standing REVIEW
    unc = rows["uncontrolled"]
    assert unc.status == "info" and "6 observation component(s) (1.0 %" in unc.text
    assert "all on 3 tie point(s)" in unc.text and "measure them on a third photo" in unc.text
    # sigma0 0.836 in [0.769, 0.915]: the one-sided test says what it says
    assert "the a-priori sigmas are pessimistic" in rows["global"].text
    # 2 rejections against 0.61 expected: P = 0.13, chance; one of them on a GCP
    assert rows["rejections"].status == "pass" and "= 0.13" in rows["rejections"].text
    assert rows["control"].status == "pass" and "point 001003 Y" in rows["control"].text
