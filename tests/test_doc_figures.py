"""Every figure the docs quote from a run comes from this test (issue 26, item 9): each
documented command is run as the user types it, and each sentence that quotes its numbers
is formatted from the run's own result folder and must stand in the page as written.

A sentence is a template: `{name:format}` is a value of the run (summary.json's fields,
and the derived ones of `values`), `[...]` matches any words in between; white space and
line breaks of the page do not count.  docs/tutorial.md's console blocks are checked by
tests/test_tutorial.py."""

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from baarda.cli import main

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT / ".." / "shared" / "data"

# name -> the command after `baarda` (OUT: the result folder; SHARED: ../shared/data)
RUNS = {
    "micmac": ["adjust", "SHARED/micmac_ign_ultracam_aerial", "-o", "OUT"],
    "micmac snooped": ["adjust", "SHARED/micmac_ign_ultracam_aerial", "-o", "OUT", "--snoop"],
    "berlin": ["adjust", "tests/data/opensfm_berlin", "-o", "OUT"],
    "berlin snooped": ["adjust", "tests/data/opensfm_berlin", "-o", "OUT", "--snoop"],
    "demo replayed": ["online", "--bundle", "--replay", "examples/demo", "-o", "OUT"],
}

# (page, run, sentence)
FIGURES = [
    ("docs/formats.md", "micmac",
     "{n_observations:,} observations, redundancy {redundancy:,}, {iterations} iterations; "
     "sigma0 {sigma0:.4f} (GNSS and IMU rows included; the tie points are better than the "
     "assumed 0.5 px: image RMS {rms_image_x:.2f} / {rms_image_y:.2f} µm = "
     "{rms_image_px:.2f} px); residual RMS of the GNSS positions X {rms_gnss_X:.3f}, Y "
     "{rms_gnss_Y:.3f}, Z {rms_gnss_Z:.3f} m, of the IMU attitudes {rms_imu:.1f} mdeg; the "
     "control point 724046's residuals {v_control_724046_X:.3f}, {v_control_724046_Y:.3f}, "
     "{v_control_724046_Z:.3f} m (w {w_control_724046_X:.2f}, {w_control_724046_Y:.2f}, "
     "{w_control_724046_Z:.2f})"),
    ("docs/formats.md", "micmac snooped",
     "With `--snoop`, {n_rejected} rejections: the GNSS Y of all {rejected_gnss_Y} photos of "
     "strip 16 (w {w_range_gnss}), then the control point's Y (w {w_range_control}) and one "
     "image y (w {w_range_image}); sigma0 {sigma0:.4f}"),
    ("docs/formats.md", "berlin",
     "{n_observations:,} observations, {n_unknowns:,} unknowns, redundancy {redundancy:,}, "
     "{iterations} Gauss-Newton iterations from the stored reconstruction"),
    ("docs/formats.md", "berlin",
     "sigma0 {sigma0:.4f} (the GPS rows left out; image RMS {rms_image_x_px:.2f} / "
     "{rms_image_y_px:.2f} px); c {c:.4f} +- {sigma_c:.4f} mm"),
    ("docs/formats.md", "berlin snooped",
     "With `--snoop`: {n_rejected} image coordinates rejected (w {w_first:.1f} down to "
     "{w_last:.1f}), {refused} removals refused (without them the adjustment does not "
     "converge), sigma0 {sigma0:.4f}, c {c:.3f} +- {sigma_c:.3f} mm"),
    ("docs/odm.md", "berlin",
     "Without snooping sigma0 is {sigma0:.2f} (with 1 px assumed)"),
    ("docs/odm.md", "berlin", "moves by 7 % with them ({c:.3f} to"),
    ("docs/odm.md", "berlin snooped", "to {c:.3f} mm at the nominal 1 µm pixel"),
    ("docs/odm.md", "berlin", "The check point GCP 0 misses by {d_gcp_0_X_abs:.1f}, "
     "{d_gcp_0_Y_abs:.1f} and {d_gcp_0_Z_abs:.1f} m"),
    ("docs/formats.md", "berlin", "GCP 0 as check point: adjusted - given = {d_gcp_0_X:.2f}, "
     "{d_gcp_0_Y:.2f}, {d_gcp_0_Z:+.2f} m"),
    ("docs/online.md", "demo replayed",
     "{replay_rows} components tested in {replay_steps} steps ({replay_reject} rejected, "
     "{replay_suspect} not checked when they were taken in); the result folder has sigma0 "
     "{sigma0:.4f} and redundancy {redundancy}"),
    ("docs/online.md", "demo replayed",
     "arrives (photo 01007, step {replay_step_01006_001008_y}): w "
     "{replay_w_01006_001008_y:.2f}, r {replay_r_01006_001008_y:.3f}, MDB "
     "{replay_mdb_01006_001008_y:.1f} µm"),
    ("docs/online.md", "demo replayed",
     "is rejected at once: w {replay_w_03008_007008_x:.2f}, r {replay_r_03008_007008_x:.3f}"),
    ("docs/online.md", "demo replayed",
     "MDB of {replay_mdb_01004_002005_x:.1f} µm when it comes (w {replay_w_01004_002005_x:.2f}, "
     "r {replay_r_01004_002005_x:.3f})"),
    ("docs/online.md", "demo replayed",
     "MDB then (w {replay_w_03002_007002_y:.2f}, r {replay_r_03002_007002_y:.3f})"),
    ("docs/odm.md", "berlin snooped",
     "snooping rejects {n_rejected} of {n_image:,} image coordinates (w from {w_first:.1f} "
     "down to {w_last:.1f}) and sigma0 falls to {sigma0:.2f}"),
]


def values(out: Path) -> dict:
    """summary.json's fields, and per kind / component / point from observations.csv:
    rms_<kind>[_<component>] (rows used), v_ and w_<kind>_<point>_<component>,
    max_abs_<kind>, max_abs_w_<kind>, rejected_<kind>_<component>, w_range_<kind> of the
    rejections ('4.3-6.3'), w_first / w_last of the log, c and sigma_c of the camera."""
    s = json.loads((out / "summary.json").read_text())
    obs = pd.read_csv(out / "observations.csv", keep_default_na=False, na_values=[""],
                      dtype={"point": str, "photo": str})
    used = obs[~obs["rejected"]]
    d = dict(s)
    for kind, g in used.groupby("kind"):
        v = g["residual"].to_numpy(float)
        d[f"rms_{kind}"] = float(np.sqrt(np.mean(v**2)))
        d[f"max_abs_{kind}"] = float(np.max(np.abs(v)))
        d[f"max_abs_w_{kind}"] = float(np.nanmax(np.abs(g["w"].to_numpy(float))))
        d[f"n_{kind}"] = len(obs[obs["kind"] == kind])
        for comp, h in g.groupby("component"):
            d[f"rms_{kind}_{comp}"] = float(np.sqrt(np.mean(h["residual"].to_numpy(float)**2)))
        for r in g.itertuples():
            d[f"v_{kind}_{r.point}_{r.component}"] = r.residual
            d[f"w_{kind}_{r.point}_{r.component}"] = r.w
    for (kind, comp), g in obs[obs["rejected"]].groupby(["kind", "component"]):
        d[f"rejected_{kind}_{comp}"] = len(g)
    px = next((c.get("pixel_mm") for c in s.get("cameras", [])), None) or 1e-3
    for c in "xy":
        if f"rms_image_{c}" in d:
            d[f"rms_image_{c}_px"] = d[f"rms_image_{c}"] * 1e-3 / px
    if "rms_image_x" in d:
        d["rms_image_px"] = np.hypot(d["rms_image_x"], d["rms_image_y"]) / np.sqrt(2) \
            * 1e-3 / px
    log = [e for e in s.get("rejection_log", []) if e["action"] == "reject"]
    if log:
        d["w_first"], d["w_last"] = abs(log[0]["value"]), abs(log[-1]["value"])
    d["refused"] = sum(e["action"] == "kept" for e in s.get("rejection_log", []))
    for kind in {o.split()[0] for e in log for o in e["observations"]}:
        w = sorted(abs(e["value"]) for e in log if e["observations"][0].startswith(kind))
        d[f"w_range_{kind}"] = f"{w[0]:.1f}" if len(w) == 1 else f"{w[0]:.1f}-{w[-1]:.1f}"
    if (out / "points.csv").is_file():  # the check points' adjusted - given: d_<point>_X
        pts = pd.read_csv(out / "points.csv", dtype={"point": str}, keep_default_na=False,
                          na_values=[""])
        for r in pts[pts["role"] == "check"].itertuples():
            for c in "XYZ":
                key = f"d_{r.point}_{c}".replace(" ", "_")
                d[key] = getattr(r, f"d{c}")
                d[key + "_abs"] = abs(d[key])
    replay = out / "replay.csv"  # baarda online --replay: the test of each component
    if replay.exists():
        t = pd.read_csv(replay, keep_default_na=False, na_values=[""],
                        dtype={"point": str, "photo": str})
        if "row" in t:  # the tests, not the verdict changes (issue 41)
            t = t[t["row"] == "test"]
        d["replay_rows"], d["replay_steps"] = len(t), int(t["step"].nunique())
        for v, g in t.groupby("verdict"):
            d[f"replay_{v}"] = len(g)
        for r in t.itertuples():
            key = f"{r.photo}_{r.point}_{r.component}"
            d[f"replay_w_{key}"], d[f"replay_r_{key}"] = r.w, r.redundancy
            d[f"replay_step_{key}"], d[f"replay_mdb_{key}"] = r.step, r.mdb
    cal = [r for r in s.get("calibration", []) if r["parameter"] == "c"]
    if cal:
        d["c"], d["sigma_c"] = cal[0]["value"], cal[0]["sigma"] or 0.0
    return d


def sentence(template: str, v: dict) -> str:
    """The template with the run's values (a regular expression: `[...]` matches any
    words, white space any white space)."""
    out, pos = [], 0
    for m in re.finditer(r"\{([^}:]+)(?::([^}]*))?\}|\[\.\.\.\]", template):
        out.append(re.escape(template[pos:m.start()]))
        if m.group(0) == "[...]":
            out.append(".*?")
        else:
            out.append(re.escape(format(v[m.group(1)], m.group(2) or "")))
        pos = m.end()
    out.append(re.escape(template[pos:]))
    return re.sub(r"(\\ )+", r"\\s+", "".join(out))


@pytest.fixture(scope="module")
def runs(tmp_path_factory, monkeypatch_module):
    monkeypatch_module.chdir(ROOT)
    done = {}

    def run(name):
        if name not in done:
            argv = RUNS[name]
            if any("SHARED" in a for a in argv) and not SHARED.is_dir():
                pytest.skip("../shared/data is not beside this checkout")
            out = tmp_path_factory.mktemp(name.replace(" ", "_")) / "out"
            argv = [a.replace("SHARED", str(SHARED)).replace("OUT", str(out)) for a in argv]
            assert main([*argv, "-q"]) in (0, 3)
            done[name] = values(out)
        return done[name]

    return run


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as mp:
        yield mp


@pytest.mark.parametrize("page, run, template", FIGURES,
                         ids=[f"{p}:{r}:{i}" for i, (p, r, _) in enumerate(FIGURES)])
def test_the_page_quotes_the_run(runs, page, run, template):
    text = " ".join((ROOT / page).read_text(encoding="utf-8").split())
    expected = sentence(template, runs(run))
    if not re.search(expected, text):
        shown = re.sub(r"\\s\+", " ", expected).replace("\\", "").replace(".*?", "[...]")
        pytest.fail(f"{page} should say, from `baarda {' '.join(RUNS[run])}`:\n{shown}")


def test_every_page_with_a_quoted_run_is_covered():
    pages = {p for p, _, _ in FIGURES}
    assert {"docs/formats.md", "docs/odm.md", "docs/online.md"} <= pages
    assert set(RUNS) == {r for _, r, _ in FIGURES}
