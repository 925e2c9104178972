"""baarda review's JSON API on the demo: the acceptance of issue 39 and its security."""

import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from review_serving import Served

from baarda.cli import main
from baarda.pipeline import prepare, snoop
from baarda.review.app import OutputLock, resumed, saver
from baarda.review.edits import Edit, read_edits, write_edits
from baarda.review.session import ReviewSession

FIRST = ("03008", "007008", "x")  # the demo's largest |w| (-8.53), snooping's first rejection


@pytest.fixture
def served(demo_session, demo_read, tmp_path):
    s = Served(demo_session, save=saver(demo_session, *demo_read, tmp_path / "out",
                                        [str(tmp_path)]))
    yield s
    s.close()


def test_flagged_list_worst_first(served):
    status, data, _ = served.request("/api/observations?status=flagged")
    assert status == 200
    rows = data["observations"]
    first = rows[0]
    assert (first["photo"], first["point"], first["component"]) == FIRST
    assert first["w"] == pytest.approx(-8.527, abs=1e-3) and first["verdict"] == "reject"
    tested = [abs(r["w"]) for r in rows if r["verdict"] == "reject"]
    assert tested == sorted(tested, reverse=True) and len(tested) == 19
    _, every, _ = served.request("/api/observations?status=all")
    assert len(every["observations"]) == 598 > len(rows)


def test_reject_reaches_snoopings_first_step_then_adjust_edits_agrees(served, demo_read,
                                                                      tmp_path):
    block, config = demo_read
    # the independent figure: data snooping's sigma0 after its first rejection
    log = snoop(prepare(block, config=config), config.tests).run.log
    assert (log[0].action, log[0].labels[0]) == ("reject", "image photo 03008 point 007008 x")
    after_first = log[1].sigma0
    assert after_first == pytest.approx(1.314, abs=5e-4)

    t0 = time.perf_counter()
    status, answer, _ = served.request("/api/edits", {
        "action": "reject", "photo": "03008", "point": "007008", "component": "x"})
    seconds = time.perf_counter() - t0
    assert status == 200
    assert answer["summary"]["sigma0"] == pytest.approx(after_first, abs=1e-8)
    assert answer["summary"]["rejected"] == 1 and seconds < 1.0
    changed = {(c["photo"], c["point"], c["component"]): c for c in answer["changed"]}
    assert changed[FIRST]["before"] == "reject" and changed[FIRST]["after"] == "rejected"

    status, saved, _ = served.request("/api/save", {})
    assert status == 200 and saved["edits"] == 1
    out = tmp_path / "out"
    edits = read_edits(out / "edits.csv")
    assert [(e.action, e.photo, e.point, e.component) for e in edits] == [("reject", *FIRST)]
    assert main(["adjust", str(block.source or "examples/demo"), "--edits",
                 str(out / "edits.csv"), "-o", str(tmp_path / "adj"), "-q"]) in (0, 3)
    a = pd.read_csv(tmp_path / "adj" / "observations.csv")
    b = pd.read_csv(out / "observations.csv")
    pd.testing.assert_frame_equal(a, b)
    assert (tmp_path / "adj" / "observations.csv").read_bytes() == \
        (out / "observations.csv").read_bytes()
    # the saved folder as INPUT: its input and its edits (baarda review OUT resumes)
    src, again = resumed(out)
    assert src.resolve() == Path(block.source).resolve() and again == edits
    resumed_session = ReviewSession(block, config, again)
    assert resumed_session.summary()["sigma0"] == pytest.approx(after_first, abs=1e-8)
    assert resumed(tmp_path) is None


def test_undo_restore_remeasure_aside(served, demo_session):
    s0 = demo_session.summary()["sigma0"]
    edit = served.request
    assert edit("/api/edits", {"action": "reject", "photo": "03008", "point": "007008",
                               "component": "x"})[0] == 200
    _, a, _ = edit("/api/edits", {"action": "undo"})
    assert a["summary"]["sigma0"] == pytest.approx(s0, abs=1e-9)
    # re-measuring the worst x at the position the block predicts without it
    ray = next(r for r in demo_session.rays("007008") if r["photo"] == "03008")
    _, a, _ = edit("/api/edits", {"action": "remeasure", "photo": "03008", "point": "007008",
                                  "x_mm": ray["pred_x"], "y_mm": ray["y"]})
    row = next(r for r in demo_session.rows() if (r["photo"], r["point"],
                                                   r["component"]) == FIRST)
    assert abs(row["w"]) < 1.0 and a["summary"]["sigma0"] < s0
    _, a, _ = edit("/api/edits", {"action": "aside", "point": "007008"})
    assert not any(r["point"] == "007008" and r["kind"] == "image"
                   for r in demo_session.rows())
    assert edit("/api/edits", {"action": "aside", "point": "007008"})[0] == 422
    for _ in range(2):
        assert edit("/api/edits", {"action": "undo"})[0] == 200
    assert demo_session.summary()["sigma0"] == pytest.approx(s0, abs=1e-9)
    assert edit("/api/edits", {"action": "undo"})[0] == 422  # nothing left to undo


def test_token_required(served):
    for path in ("/", "/api/summary", "/api/observations", "/static/review.js"):
        assert served.request(path, token=False)[0] == 403
    assert served.request("/api/summary", token=False,
                          headers={"X-Baarda-Token": "wrong"})[0] == 403
    assert served.request(f"/api/summary?token={served.token}", token=False)[0] == 200
    assert served.request("/api/summary", token=False,
                          headers={"Authorization": f"Bearer {served.token}"})[0] == 200
    assert served.request("/api/edits", {"action": "undo"}, token=False)[0] == 403
    # a page of another site that resolves to 127.0.0.1 (DNS rebinding): refused
    assert served.request("/api/summary", headers={"Host": "evil.example"})[0] == 403


def test_ids_are_looked_up_never_paths(served):
    for q in ("photo=../../etc/passwd&point=007008", "photo=03008&point=../../etc/passwd",
              "photo=/etc/passwd&point=007008"):
        status, body, _ = served.request("/api/chip?" + q)
        assert status == 404 and "unknown" in body["error"]
    status, body, _ = served.request("/api/chip?photo=03008&point=007008")
    assert status == 404 and body["error"] == "no image of photo 03008"  # the demo has none


def test_bad_requests_are_answered_and_the_server_goes_on(served):
    bad = [(b"{not json", 400), (b"[1, 2]", 422), (b'{"action": "explode"}', 422),
           (b'{"action": "reject", "photo": "03008", "point": "007008", "component": "z"}',
            422),
           (b'{"action": "remeasure", "photo": "03008", "point": "007008"}', 422),
           (b'{"action": "reject", "photo": 3, "point": "007008", "component": "x"}', 422),
           (b'{"action": "reject", "photo": "03008", "point": "nope", "component": "x"}',
            404),
           (b'{"action": "reject", "point": "001003", "component": "X"}', 422),
           (b'{"action": "undo"}', 422)]
    for raw, code in bad:
        status, body, _ = served.request("/api/edits", raw=raw)
        assert (status, isinstance(body, dict) and bool(body.get("error"))) == (code, True), raw
    assert served.request("/api/observations?status=weird")[0] == 400
    assert served.request("/api/edits", raw=b"x" * 100_000)[0] == 413
    status, summary, _ = served.request("/api/summary")
    assert status == 200 and summary["edits"] == 0


def test_a_second_review_of_the_same_out_is_refused(tmp_path):
    lock = OutputLock(tmp_path / "out")
    with pytest.raises(OSError, match="another baarda review"):
        OutputLock(tmp_path / "out")
    lock.release()
    OutputLock(tmp_path / "out").release()


def test_edits_file_round_trip_and_errors(tmp_path):
    edits = [Edit("reject", "03008", "007008", "x", time="t"),
             Edit("remeasure", "03008", "007008", "", 1.25, -3.5, "t"), Edit("undo")]
    write_edits(tmp_path / "edits.csv", edits)
    back = read_edits(tmp_path / "edits.csv")
    assert back[:2] == edits[:2] and back[2].action == "undo"
    assert np.isnan(back[2].x)
    (tmp_path / "bad.csv").write_text("action,photo,point,component,x,y,time\n"
                                      "remeasure,03008,007008,,1.0,abc,t\n")
    with pytest.raises(ValueError, match=r"bad.csv, line 2, column 'y'"):
        read_edits(tmp_path / "bad.csv")


def test_separability_is_brought_up_to_date(demo_session, demo_read):
    """A rejection answers with the w-test correlations of the block before (provisional);
    those of the block after follow in the background and equal a fresh adjustment's."""
    from baarda.review.session import adjusted

    demo_session.edit({"action": "reject", "photo": "03008", "point": "007008",
                       "component": "x"})
    demo_session.settle(120)
    assert demo_session.summary()["separability"] == "current"
    fresh = adjusted(*demo_read, demo_session.edits).qc.quality
    q = demo_session.state.qc.quality
    np.testing.assert_allclose(q.rho_max, fresh.rho_max, rtol=0, atol=1e-9)
    assert np.array_equal(q.rho_partner, fresh.rho_partner)
    before = adjusted(*demo_read, []).qc.quality
    assert np.nanmax(np.abs(before.rho_max - fresh.rho_max)) > 1e-3  # it did change


def test_adjust_edits_bad_input(tmp_path, capsys):
    demo = str(Path(__file__).resolve().parents[2] / "examples" / "demo")
    bad = tmp_path / "edits.csv"
    bad.write_text("action,photo,point,component,x,y,time\nreject,03008,nope,x,,,t\n")
    assert main(["adjust", demo, "--edits", str(bad), "-o", str(tmp_path / "o1")]) == 2
    assert "point nope on photo 03008: not in the block" in capsys.readouterr().err
    good = tmp_path / "good.csv"
    write_edits(good, [Edit("reject", *FIRST, time="t")])
    assert main(["adjust", demo, "--edits", str(good), "--snoop", "-o",
                 str(tmp_path / "o2")]) == 2
    assert "--edits and --snoop" in capsys.readouterr().err
    assert not (tmp_path / "o1").exists() and not (tmp_path / "o2").exists()


def test_each_kind_has_its_own_unit():
    """An IMU row's MDB is an angle, in thousandths of the project's angle unit (was
    labelled m); image µm, control and GNSS m (baarda/kinds.py)."""
    from baarda.options import Config
    from baarda.simulate.aerial import FlightPlan, simulate_block

    plan = FlightPlan(strips=2, photos_per_strip=4, relief_m=80.0, seed=5,
                      gnss_sigma_m=0.05, imu_sigma_deg=0.005)
    block, _ = simulate_block(plan)
    assert block.settings.angle_unit == "gon"
    session = ReviewSession(block, Config())
    try:
        rows = session.observations("all")
    finally:
        session.close()
    units = {(r["kind"], r["unit"]) for r in rows}
    assert units == {("image", "µm"), ("control", "m"), ("gnss", "m"), ("imu", "mgon")}
    imu = [r["mdb"] for r in rows if r["kind"] == "imu"]
    assert all(1 < m < 1000 for m in imu)  # mgon, not rad
