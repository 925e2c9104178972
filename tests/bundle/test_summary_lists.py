"""A summary lists at most MAX_LISTED cameras and parameter tests and counts the rest (a BAL
block of 5,000 cameras printed 15,000 such lines; issue 40's run): the result's files hold
every one (cameras.csv, summary.json's "hypotheses")."""

import numpy as np
from bal_reference import _synthetic

import baarda
from baarda.output.format_files import write_bal
from baarda.sections import MAX_LISTED, at_most


def test_a_block_of_many_cameras_lists_the_first_and_counts_the_rest(tmp_path):
    path = tmp_path / "problem-24.txt"
    write_bal(_synthetic(seed=3, ncam=24), path)
    qc = baarda.assess(baarda.adjust(baarda.read(str(path))))
    lines = qc.summary().splitlines()
    cameras = [x for x in lines if x.startswith("camera ")]
    assert len(cameras) == MAX_LISTED == 20
    assert "... and 4 more camera(s) (every parameter of every camera in cameras.csv)" in lines
    params = [t for t in qc.hypotheses if t.parameters]
    assert len(params) == 48  # f, and k1 with k2, of 24 cameras
    shown = [x for x in lines if x.startswith("  ") and " of camera " in x and "T/q" in x]
    assert [x.strip() for x in shown] == [t.summary() for t in params[:MAX_LISTED]]
    sig = sum(bool(t.rejected) for t in params[MAX_LISTED:])
    assert f"  ... and 28 more test(s): {sig} significant, {28 - sig} not (every test in " \
        "summary.json's \"hypotheses\")" in lines
    assert len(qc.to_dict()["hypotheses"]) == len(qc.hypotheses)  # every test stays there


def test_at_most_keeps_a_list_one_line_over():
    items = [f"x{i}" for i in range(5)]
    assert at_most(items, "x", limit=4) == items  # "and 1 more" would take a line too
    assert at_most(items, "x", limit=3) == ["x0", "x1", "x2", "... and 2 more x"]
    assert at_most([], "x") == [] and at_most(items, "x") == items


def test_tie_points_left_out_are_counted_in_one_note_control_and_check_by_name():
    """Points without two rays: each control or check point in a note of its own, the tie
    points in one note per cause with their names (the first 20; a large BAL problem can
    leave out thousands)."""
    from baarda.bundle.geometry import usable_points
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=8, check_points=2, seed=4))
    pts, im = block.points, block.image
    ties = np.flatnonzero(pts.role == "tie")[:25]
    assert len(ties) == 25
    check = int(np.flatnonzero(pts.role == "check")[0])
    drop = np.zeros(len(im.point), bool)
    for j in [*ties[:23], check]:  # one ray left: the first of the point's rows kept
        rows = np.flatnonzero(im.point == j)
        drop[rows[1:]] = True
    for j in ties[23:]:  # no ray left
        drop[im.point == j] = True
    ok, notes = usable_points(block.select_image(~drop))
    assert not ok[ties].any() and not ok[check]
    names = [str(pts.ids[j]) for j in ties]
    assert notes[0] == (f"check point {pts.ids[check]} is measured on one photo only (one "
                        "ray cannot be intersected): left out")
    assert notes[1] == ("2 tie points have no ray (measured on no photo, or their rays left "
                        "out: see the notes above): left out: " + ", ".join(names[23:]))
    assert notes[2] == ("23 tie points are measured on one photo only (one ray cannot be "
                        "intersected): left out: " + ", ".join(names[:20]) + " and 3 more")
    assert len(notes) == 3
