"""Issue 26: every number the user reads is right.  The invariants of every result folder
(`baarda check`: sum of r = redundancy; sigma0^2 = sum (v/sigma)^2 over the rows used /
redundancy = the global test's statistic; every RMS line recomputed from the rows it
covers), on simulated blocks with GNSS, IMU, distances, self-calibration, fixed control and
--vce, with and without --snoop, and on every real data set; standard deviations against a
dense computation; the written tables read back equal to the API's arrays."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from baarda.cli import main
from baarda.report.check import check_folder

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / ".." / "shared" / "data"


def need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"{path} is not beside this checkout (../shared/data)")
    return path


def adjust(tmp_path, source, *options) -> Path:
    out = tmp_path / "out"
    rc = main(["adjust", str(source), "-o", str(out), "-q", *options])
    assert rc in (0, 3), rc
    return out


def hold(out: Path) -> dict:
    """Every invariant of the folder holds; its summary.json."""
    findings = check_folder(out)
    bad = [f.line() for f in findings if not f.ok]
    assert not bad, "\n".join(bad)
    names = {f.name for f in findings}
    assert {"sum of the redundancy numbers = redundancy", "sigma0 = sqrt(vTPv / redundancy)",
            "global test statistic = sigma0^2"} <= names, names
    return json.loads((out / "summary.json").read_text())


def recomputed_sigma0(out: Path) -> float:
    """sqrt(sum (v/sigma)^2 / redundancy) from observations.csv, independently of check."""
    obs = pd.read_csv(out / "observations.csv", keep_default_na=False, na_values=[""])
    used = obs[~obs["rejected"]]
    s = json.loads((out / "summary.json").read_text())
    return float(np.sqrt(np.sum((used["residual"] / used["sigma"]) ** 2) / s["redundancy"]))


@pytest.fixture(scope="module")
def gnss_block(tmp_path_factory):
    """The issue's block: 3 x 6 photos with GNSS (5 cm) and IMU (0.005 deg)."""
    root = tmp_path_factory.mktemp("gnss")
    assert main(["simulate", "-o", str(root / "b"), "--strips", "3", "--photos", "6",
                 "--gnss", "0.05", "--imu", "0.005", "--seed", "1"]) == 0
    return root / "b"


def test_sigma0_counts_the_gnss_and_imu_rows(gnss_block, tmp_path):
    """It printed 0.7836 (image and control rows only); the global test said 0.9629."""
    out = adjust(tmp_path, gnss_block)
    s = hold(out)
    assert s["sigma0"] == pytest.approx(recomputed_sigma0(out), rel=1e-6)
    assert s["sigma0"] == pytest.approx(0.9629, abs=1e-4)
    assert s["global_test"]["statistic"] == pytest.approx(s["sigma0"] ** 2, rel=1e-12)


def test_standard_deviations_equal_a_dense_computation(gnss_block, tmp_path):
    """photos.csv and points.csv: sigma0 x sqrt(diag of the dense (A'PA)^-1), GNSS and IMU
    rows included, to 1e-6."""
    from dense import dense_system

    from baarda.block.rotation import rad_to_angle
    from baarda.bundle.bundle_model import BundleModel
    from baarda.output.bundle_results import write_results
    from baarda.pipeline import adjust as adjust_block
    from baarda.pipeline import assess, read

    res = adjust_block(read(gnss_block))
    assert res.problem.gnss_imu.m > 0
    model = BundleModel(res)
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    v = model.residuals
    red = int(np.count_nonzero(p)) - a.shape[1]
    s0 = float(np.sqrt(np.sum(p * v**2) / red))
    assert res.sigma0 == pytest.approx(s0, rel=1e-9)
    std = s0 * np.sqrt(np.diag(qxx))
    nf = len(res.block.photos)
    write_results(tmp_path / "o", assess(res))
    photos = pd.read_csv(tmp_path / "o" / "photos.csv", dtype={"photo": str})
    eo_std = std[:6 * nf].reshape(nf, 6)
    np.testing.assert_allclose(photos[["sigma_X0", "sigma_Y0", "sigma_Z0"]], eo_std[:, :3],
                               rtol=1e-6)
    unit = res.block.settings.angle_unit
    np.testing.assert_allclose(photos[["sigma_omega", "sigma_phi", "sigma_kappa"]],
                               rad_to_angle(eo_std[:, 3:], unit), rtol=1e-6)
    pb = res.problem
    points = pd.read_csv(tmp_path / "o" / "points.csv", dtype={"point": str})
    npn = len(pb.elim_ids)
    pt_std = std[6 * nf:6 * nf + 3 * npn].reshape(npn, 3)
    rows = pb.remap[pb.elim_ids]
    np.testing.assert_allclose(points[["sigma_X", "sigma_Y", "sigma_Z"]].to_numpy()[rows],
                               pt_std, rtol=1e-6)
    hold(tmp_path / "o")


def test_distances_self_calibration_and_fixed_control(tmp_path):
    """A block with a scale bar, five camera parameters, a fixed control point and per-axis
    image sigmas (tests/bundle/test_calibration_dense.py): sigma0 from every row, the
    camera parameters' standard deviations = the dense computation."""
    from dense import dense_system

    from baarda.block.photo_block import Distances
    from baarda.bundle.bundle_model import BundleModel
    from baarda.output.bundle_results import write_results
    from baarda.pipeline import adjust as adjust_block
    from baarda.pipeline import snoop
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=150.0,
                                             side_overlap=0.6, blunders=2, seed=21))
    cams = replace(block.cameras, model=np.array(["brown"], dtype=object),
                   coefficients=np.array([[1e-6, 0, 0, 2e-6, -1e-6, 0, 0]]))
    pts = block.points
    sigma = pts.sigma.copy()
    sigma[np.flatnonzero(pts.role == "control")[0]] = 0.0
    tie = np.flatnonzero(pts.role == "tie")
    a, b = tie[2], tie[-3]
    xa, xb = (np.array(truth["points"][pts.ids[j]]) for j in (a, b))
    dist = Distances(["bar"], np.array([a]), np.array([b]),
                     np.array([float(np.linalg.norm(xa - xb)) + 0.01]), np.array([0.02]))
    block = replace(block, cameras=cams,
                    settings=replace(block.settings,
                                     calibration_free=(("c", "k1", "p1", "p2", "b1"),)),
                    points=replace(pts, sigma=sigma), distances=dist)
    res = adjust_block(block)
    model = BundleModel(res)
    am, p = dense_system(model)
    qxx = np.linalg.inv(am.T @ (p[:, None] * am))
    red = int(np.count_nonzero(p)) - am.shape[1]
    s0 = float(np.sqrt(np.sum(p * model.residuals**2) / red))
    assert res.sigma0 == pytest.approx(s0, rel=1e-9) and res.redundancy == red
    n = res.problem.calibration.n
    ng = res.problem.system.ng
    cam_q = qxx[-ng:, -ng:][:n, :n]
    cal = res.problem.calibration
    cols = dict(zip(cal.free_index[0].tolist(), cal.columns[0].tolist(), strict=True))
    rows = res.camera_table()
    dense_std = s0 * np.sqrt(np.diag(cam_q))
    est = [(r["sigma"], dense_std[cols[j]]) for j, r in enumerate(rows) if r["estimated"]]
    assert len(est) == n == 5
    np.testing.assert_allclose(*zip(*est, strict=True), rtol=1e-6)
    qc = snoop(block)
    write_results(tmp_path / "snooped", qc)
    s = hold(tmp_path / "snooped")
    assert s["n_rejected"] >= 1 and "distance" in set(qc.model.kind)


def test_fixed_control_equals_a_tiny_sigma(tmp_path):
    """Issue 26, item 4: a point's Z given sigma 0 ("held fixed") is held: the same
    adjustment as sigma 1e-9, that component not an observation and not tested."""
    proj = tmp_path / "p"
    shutil.copytree(ROOT / "examples" / "demo", proj)
    gp = proj / "ground_points.csv"
    text = gp.read_text()
    row = "002005,2760.0,0.0,2.1555934203998195,,,0.1,control"
    assert row in text
    outs = {}
    for sz in ("0", "1e-9"):
        gp.write_text(text.replace(row, row.replace(",0.1,control", f",{sz},control")))
        out = tmp_path / f"o{sz}"
        assert main(["adjust", str(proj), "-o", str(out), "-q"]) == 0
        outs[sz] = (hold(out), pd.read_csv(out / "points.csv", dtype={"point": str}),
                    pd.read_csv(out / "observations.csv", dtype={"point": str},
                                keep_default_na=False, na_values=[""]))
    (s0, p0, o0), (s9, p9, o9) = outs["0"], outs["1e-9"]
    assert s0["sigma0"] == pytest.approx(s9["sigma0"], rel=1e-6)
    assert s0["redundancy"] == s9["redundancy"]
    np.testing.assert_allclose(p0[["X", "Y", "Z"]], p9[["X", "Y", "Z"]], atol=1e-6)
    held = p0[p0["point"] == "002005"]
    assert float(held["Z"].iloc[0]) == 2.1555934203998195 and float(held["sigma_Z"].iloc[0]) == 0
    is_z = (o0["point"] == "002005") & (o0["kind"] == "control")
    assert not is_z.any()  # not an observation
    assert ((o9["point"] == "002005") & (o9["kind"] == "control")).sum() == 1


@pytest.mark.parametrize("options", [[], ["--snoop"], ["--vce"], ["--snoop", "--vce"],
                                     ["--snoop", "--tau", "--by-point"]])
def test_demo_every_mode(tmp_path, options):
    hold(adjust(tmp_path, ROOT / "examples" / "demo", *options))


def test_micmac_gnss_imu_block(tmp_path):
    """sigma0 0.4469 with the GNSS and IMU rows (0.4371 printed before, without them);
    photos.csv and points.csv read back equal the API's Lambert-93 coordinates."""
    from baarda.pipeline import adjust as adjust_block
    from baarda.pipeline import read

    src = need(DATA / "micmac_ign_ultracam_aerial")
    out = adjust(tmp_path, src)
    s = hold(out)
    assert s["sigma0"] == pytest.approx(0.4469, abs=1e-4)
    assert s["sigma0"] == pytest.approx(recomputed_sigma0(out), rel=1e-6)
    res = adjust_block(read(src))
    frame = res.block.frame
    eo = frame.eo_from_local(res.coordinates.eo)
    photos = pd.read_csv(out / "photos.csv", dtype={"photo": str})
    assert np.abs(photos[["X0", "Y0", "Z0"]].to_numpy() - eo[:, :3]).max() < 1e-4
    assert photos["Y0"].abs().min() > 6e6  # Lambert-93 northings
    points = pd.read_csv(out / "points.csv", dtype={"point": str})
    xyz = frame.from_local(res.coordinates.xyz)
    assert np.abs(points[["X", "Y", "Z"]].to_numpy() - xyz).max() < 1e-4
    # item 7: units everywhere, reprojection errors in px (the camera's 4 µm pixels)
    from baarda.io.result_folder import read_results
    from baarda.report.quality_report import image_parts
    from baarda.report.stats import group_statistics, weakest

    rf = read_results(out)
    assert rf.units["gnss"] == "m" and rf.units["imu"] == "mdeg"
    assert all(g.unit for g in group_statistics(rf.obs, rf.units))
    assert set(weakest(rf.obs, 5, rf.units)["largest MDB (per kind)"]["unit"]) == \
        {"µm", "m", "mdeg"}
    parts = image_parts(rf)
    assert "1 px = 4 µm" in " ".join(p.text for p in parts)
    t = [p.table for p in parts if p.kind == "table"][0]
    assert "RMS x px" in t.columns


def test_micmac_snooped(tmp_path):
    hold(adjust(tmp_path, need(DATA / "micmac_ign_ultracam_aerial"), "--snoop"))


def test_aicon_sigma0_is_the_protocols(tmp_path):
    """AICON's protocol: sigma0 0.000405 mm = 0.8107 x the a-priori 0.5 µm (the scale bar
    row included; 0.8087 printed before)."""
    out = adjust(tmp_path, need(DATA / "aicon_jaicov_closerange"))
    s = hold(out)
    assert s["sigma0"] * 0.5e-3 == pytest.approx(0.000405, abs=5e-7)
    assert s["sigma0"] == pytest.approx(0.8107, abs=1e-4)


@pytest.mark.parametrize("source", [
    "dbat_sxb_aerial/dbat_script/sxb.xml", "colmap_maupertuis", "opensfm_berlin"])
def test_real_data_sets(tmp_path, source):
    hold(adjust(tmp_path, need(DATA / source)))


@pytest.mark.slow
def test_camcal_self_calibration_snooped(tmp_path):
    src = need(DATA / "dbat_camcal_closerange" / "dbat_script")
    script = src / "camcaldemo.xml"
    hold(adjust(tmp_path, script, "--snoop"))


@pytest.mark.slow
def test_bal_free_intrinsics(tmp_path):
    out = adjust(tmp_path, need(DATA / "bal" / "problem-49-7776-pre.txt.bz2"),
                 "--calibrate", "none")
    hold(out)


@pytest.mark.slow
def test_berlin_snooping_never_builds_on_a_diverged_refit(tmp_path):
    """Issue 26, item 2: from the 48th rejection on the refits diverged (point 236 ran
    off) and the written block collapsed.  Now the two removals whose refit does not
    converge are refused and logged with the reason, the snooping ends, and the camera
    centres keep their spread (within 15 % of the adjustment without snooping: the focal
    length moves by 7 % with the 191 rejections of this 3-photo block)."""
    src = need(DATA / "opensfm_berlin")
    plain = adjust(tmp_path / "plain", src)
    out = adjust(tmp_path / "snooped", src, "--snoop")
    s = hold(out)
    assert s["converged"] and s["snooping_converged"] and s["snooping_incomplete"] is None
    kept = [e for e in s["rejection_log"] if e["action"] == "kept"]
    assert kept and all("does not converge" in e["reason"] for e in kept)
    assert "point 236" in kept[0]["observations"][0]
    spread = {}
    for name, folder in (("plain", plain), ("snooped", out)):
        c = pd.read_csv(folder / "photos.csv")[["X0", "Y0", "Z0"]].to_numpy()
        spread[name] = np.linalg.norm(c - c.mean(axis=0), axis=1).max()
    assert abs(spread["snooped"] / spread["plain"] - 1) < 0.15, spread
    # sigma0 1.1101 with the GPS rows (issue 41: left out, they fix the roll only weakly)
    assert s["n_rejected"] == 191 and s["sigma0"] == pytest.approx(1.1118, abs=1e-4)


def test_one_verdict_per_line_and_the_iterations_the_console_showed(tmp_path, capsys):
    """Issue 26, item 8: the demo's B-method line (REJECTED) says it is not the verdict and
    is not coloured as the headline; the iterations are the first adjustment's (4, as the
    progress lines show) with the re-adjustments of snooping counted beside them."""
    from baarda.io.result_folder import read_results
    from baarda.pipeline import read, snoop
    from baarda.report.html_report import html_report

    shown = []  # what the progress display shows (on a terminal)
    snoop(read(ROOT / "examples" / "demo"), progress=shown.append)
    assert any(m.startswith("iteration 4: converged") for m in shown)
    out = tmp_path / "o"
    assert main(["adjust", str(ROOT / "examples" / "demo"), "-o", str(out), "--snoop"]) == 0
    s = hold(out)
    assert s["iterations"] == 4 and s["readjustments"] == 4
    lines = [x for sec in s["sections"] for x in sec["lines"]]
    assert "iterations 4 (converged), then 4 re-adjustment(s) by data snooping (the last: " \
        "3 iteration(s))" in " ".join(lines)
    b = [x for x in lines if x.startswith("global test by the B-method")][0]
    assert "-> REJECTED (not the verdict: the test at alpha 0.05 decides" in b
    html = html_report(read_results(out))
    assert '<span class="ok">global test at alpha 0.05' in html
    assert '<span class="note">global test by the B-method' in html


def test_snooping_stopped_at_its_limit_says_so_first(tmp_path):
    """Issue 26, item 2: a snooping that reaches its step limit is reported as incomplete
    on the first line of the text, HTML and quality reports, with the number of components
    still significant."""
    from baarda.io.result_folder import read_results
    from baarda.output.bundle_results import write_results
    from baarda.output.verdict import failures
    from baarda.pipeline import read, snoop
    from baarda.report.html_report import html_report
    from baarda.report.quality_html import quality_page
    from baarda.report.text_report import text_report

    qc = snoop(read(ROOT / "examples" / "demo"), max_iterations=2)
    assert not qc.run.converged and qc.run.remaining == 7
    text = ("snooping incomplete: 7 component(s) still significant when it stopped at its "
            "limit of 2 step(s)")
    assert qc.run.incomplete.startswith(text)
    write_results(tmp_path / "o", qc)
    res = read_results(tmp_path / "o")
    assert failures(res.summary) == [qc.run.incomplete.replace("snooping incomplete",
                                                      "SNOOPING INCOMPLETE")]
    assert text_report(res).split("\n")[2].startswith("SNOOPING INCOMPLETE: 7 component(s)")
    html = html_report(res)
    assert html.index("SNOOPING INCOMPLETE") < html.index("<nav>")
    page = quality_page(res)
    assert page.index("SNOOPING INCOMPLETE") < page.index('<section id="summary">')


@pytest.mark.slow
def test_levenberg_marquardt_on_the_command_line(tmp_path, capsys):
    """Issue 26, item 5: `--damping lm` on BAL Ladybug-49 with its free intrinsics raised
    GeometryError from inside the solver; now it ends like Gauss-Newton: exit 3 with the last
    sound estimate and the reason, no traceback."""
    src = need(DATA / "bal" / "problem-49-7776-pre.txt.bz2")
    out = tmp_path / "o"
    rc = main(["adjust", str(src), "-o", str(out), "--damping", "lm", "-q"])
    err = capsys.readouterr().err
    assert rc in (0, 3) and "Traceback" not in err
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] is (rc == 0)
    if rc == 3:
        assert any("diverged" in n or "not converged" in n for n in s["notes"])


@pytest.mark.slow
def test_gauss_newton_divergence_continues_with_levenberg_marquardt(tmp_path, capsys):
    """Gauss-Newton diverges on BAL Ladybug-49 with its free intrinsics; issue 40: the
    default command continues with Levenberg-Marquardt from the last sound estimate and the
    notes say so (exit 0 when it converges, else 3 with its reason)."""
    src = need(DATA / "bal" / "problem-49-7776-pre.txt.bz2")
    out = tmp_path / "o"
    rc = main(["adjust", str(src), "-o", str(out), "-q"])
    s = json.loads((out / "summary.json").read_text())
    assert rc in (0, 3) and s["converged"] is (rc == 0)
    assert any(n.startswith("Gauss-Newton diverged at iteration") and
               "Levenberg-Marquardt continued from the last sound estimate" in n
               for n in s["notes"])
    assert "Traceback" not in capsys.readouterr().err


def test_check_of_a_result_that_did_not_converge_says_so(tmp_path):
    """Issue 41: `baarda check` on an adjustment that did not converge (BAL Ladybug-49 with
    free intrinsics: the sum of r 39892.45 for a redundancy 39892) failed with exit 5 as if
    the file were wrong.  It now says the adjustment did not converge and checks what still
    holds (the counts, vTPv, sigma0); the same rows of a converged result still fail."""
    from dataclasses import replace

    from baarda.io.result_folder import read_results
    from baarda.report.check import check_results

    res = read_results(adjust(tmp_path, "examples/demo"))
    obs = res.obs.copy()
    # as the last iterate of a diverged block: one row's r off by 0.45, its sigma_v, w and
    # MDB consistent with it (the row relations hold, the sum does not)
    i = obs.index[(obs["redundancy"] < 0.5) & ~obs["rejected"].astype(bool)
                  & obs["w"].notna()][0]
    r = obs.loc[i, "redundancy"] + 0.45
    sv = obs.loc[i, "sigma"] * np.sqrt(r)
    obs.loc[i, ["redundancy", "sigma_residual", "w", "mdb"]] = [
        r, sv, -obs.loc[i, "residual"] / sv,
        res.summary["delta0"] * obs.loc[i, "sigma"] / np.sqrt(r)]
    bad = [f for f in check_results(replace(res, obs=obs)) if not f.ok]
    assert {f.name for f in bad} == {"sum of the redundancy numbers = redundancy"}
    summary = {**res.summary, "converged": False,
               "adjustments": {k: {**v, "converged": False}
                               for k, v in res.summary["adjustments"].items()}}
    findings = check_results(replace(res, obs=obs, summary=summary))
    said = [f for f in findings if f.verdict == "not converged"]
    assert said and all(f.recomputed == pytest.approx(summary["redundancy"] + 0.45)
                        for f in said)  # the adjustment's and summary.json's top level
    assert all(f.line().strip().startswith("not converged  ") and
               "the adjustment did not converge" in f.line() for f in said)
    assert all(f.ok for f in findings)
    assert {"sigma0 = sqrt(vTPv / redundancy)", "global test statistic = sigma0^2",
            "redundancy = observations - unknowns"} <= {f.name for f in findings}
