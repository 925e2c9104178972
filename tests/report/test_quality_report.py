"""The quality report of issue 20 (report/quality_report.py) as HTML and PDF: camera
parameters with standard deviations and correlations, the GCP and check-point tables; the
PDF's pages rendered to PNG with pypdfium2 (a wheel, in the test extra) and checked."""

import json

import numpy as np
import pypdfium2 as pdfium
import pytest

from baarda.cli import main
from baarda.io.result_folder import read_results
from baarda.output.project_files import write_project
from baarda.report.quality_report import quality_content
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """A simulated block with self-calibration (c, x0, y0), GNSS and check points, snooped."""
    tmp = tmp_path_factory.mktemp("quality")
    b, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, relief_m=40.0,
                                     check_points=3, gnss_sigma_m=0.1, seed=5))
    write_project(b, tmp / "project")
    out = tmp / "out"
    assert main(["adjust", str(tmp / "project"), "-o", str(out), "-q", "--snoop",
                 "--calibrate", "c,x0,y0"]) == 0
    assert main(["report", str(out), "--quality", str(tmp / "q.html"), "--pdf",
                 str(tmp / "q.pdf"), "-q"]) == 0
    return tmp


@pytest.mark.slow
def test_content_is_read_from_the_results(results):
    res = read_results(results / "out")
    parts = quality_content(res)
    heads = [p.title for p in parts if p.kind == "heading"]
    assert heads[:4] == ["Summary", "Camera calibration", "Ground control and check points",
                         "GNSS positions of the projection centres"]
    tables = {p.title: p.table for p in parts if p.kind == "table"}
    cam = tables["camera parameters"]
    est = cam[cam["estimated"]]
    assert list(est["parameter"]) == ["c", "x0", "y0"] and (est["sigma"] > 0).all()
    s = json.loads((results / "out" / "summary.json").read_text())
    by_name = {r["parameter"]: r for r in s["calibration"]}
    assert est["sigma"].tolist() == [by_name[p]["sigma"] for p in ("c", "x0", "y0")]
    corr = tables["correlations of camera cam"]
    m = corr[["c", "x0", "y0"]].to_numpy(float)
    assert np.allclose(np.diag(m), 1.0) and np.allclose(m, m.T)
    assert len(tables["control points"]) == (res.obs["kind"] == "control").groupby(
        res.obs["point"]).any().sum()
    assert len(tables["check points"]) == 3
    assert len(tables["GNSS residuals"]) == 18
    assert set(tables["reprojection errors"]["photo"]) == set(res.photos["photo"])


def test_html(results):
    h = (results / "q.html").read_text(encoding="utf-8")
    for ident in ("q-camera-parameters", "q-correlations-of-camera-cam", "q-control-points",
                  "q-check-points", "q-gnss-residuals", "q-reprojection-errors",
                  "q-observations", "q-external-reliability"):
        assert f'id="{ident}"' in h
    # the heat map, r and w, and the geometry: camera centres, GCP vectors, overlap
    assert h.count('src="data:image/png;base64,') == 2 + 3
    for fig in ("Camera-centres", "Control-and-check-point-vectors", "Image-overlap"):
        assert f'id="fig-{fig}"' in h


def test_pdf_pages_render(results, tmp_path):
    pdf = pdfium.PdfDocument(str(results / "q.pdf"))
    assert len(pdf) >= 2
    text = ""
    for i in range(len(pdf)):
        page = pdf[i]
        image = page.render(scale=1.0).to_pil()
        image.save(tmp_path / f"page{i}.png")
        a = np.asarray(image.convert("L"), float)
        assert a.shape[0] > a.shape[1] > 500  # A4 portrait
        assert (a < 128).mean() > 0.001  # printed, not blank
        text += page.get_textpage().get_text_range() + "\n"
    for words in ("Camera calibration", "Ground control and check points",
                  "Correlations of camera", "Control points", "Check points", "RMS", "x0",
                  "GNSS positions",
                  "Reprojection errors per image", "Data snooping log",
                  "External reliability"):
        assert words in text
    # the heat map is a picture (after the first page's quality check): many colours
    colours = [len(np.unique(np.asarray(pdf[i].render(scale=1.0).to_pil().convert("RGB"),
                                        int).reshape(-1, 3), axis=0)) for i in range(len(pdf))]
    assert max(colours[1:]) > 50


@pytest.mark.slow
def test_main_html_report_has_the_camera_and_control_tables(results):
    """baarda report OUT -o report.html: the camera parameters, their correlations (cells
    coloured like the heat map) and the GCP tables, without extra images."""
    out = results / "report.html"
    assert main(["report", str(results / "out"), "-o", str(out), "-q"]) == 0
    h = out.read_text(encoding="utf-8")
    assert 'id="calibration"' in h and "Correlations of camera cam" in h
    assert "Control points" in h and "Check points" in h and "GNSS residuals" in h
    assert 'style="background:#' in h


def test_reprojection_errors_pair_x_and_y_of_the_same_image_point():
    """A rejected x must not shift the pairing of the photo's other x and y residuals: the
    error vector of each point is the hypot of its own two components (hand-computed)."""
    from types import SimpleNamespace

    import pandas as pd

    from baarda.report.quality_report import image_parts

    rows = []
    for pt, (vx, vy, rej_x) in {"a": (3.0, 4.0, True), "b": (6.0, 8.0, False),
                                "c": (5.0, 12.0, False)}.items():
        rows += [dict(kind="image", photo="p1", point=pt, component="x", residual=vx,
                      rejected=rej_x),
                 dict(kind="image", photo="p1", point=pt, component="y", residual=vy,
                      rejected=False)]
    res = SimpleNamespace(obs=pd.DataFrame(rows), summary={}, sections=[])
    t = [p for p in image_parts(res) if p.kind == "table"][0].table
    row = t.iloc[0]
    assert row["points"] == 2  # b and c: a has no x
    assert row["max error µm"] == pytest.approx(13.0)  # c: hypot(5, 12)
    assert row["mean error µm"] == pytest.approx(11.5)  # (10 + 13) / 2
    assert row["RMS x µm"] == pytest.approx(np.sqrt((36 + 25) / 2))
    assert row["RMS y µm"] == pytest.approx(np.sqrt((16 + 64 + 144) / 3))


def test_camera_parameters_initial_to_adjusted_and_the_distortion_plot(tmp_path):
    """Issue 31, item 4: every camera parameter as given and adjusted with the change in %,
    and the adjusted distortion over the measured image area (berlin: c, k1, k2 free), its
    largest correction recomputed from Brown's radial formula at the area's corners."""
    from baarda.report.quality_report import camera_parts

    out = tmp_path / "o"
    assert main(["adjust", "tests/data/opensfm_berlin", "-o", str(out), "-q"]) == 0
    res = read_results(out)
    parts = camera_parts(res)
    t = [p.table for p in parts if p.kind == "table" and p.title == "camera parameters"][0]
    rows = {r["parameter"]: r for r in t.to_dict("records")}
    c, k1, k2 = (rows[p] for p in ("c", "k1", "k2"))
    for r in (c, k1, k2):
        assert r["change %"] == pytest.approx(100 * (r["value"] - r["initial"])
                                              / abs(r["initial"]), rel=1e-12)
    assert c["initial"] == pytest.approx(2.838589, abs=1e-6)  # OpenSfM's focal, mm
    assert np.isnan(rows["x0"]["change %"])  # held
    fig = [p for p in parts if p.kind == "figure" and p.title.startswith("distortion")]
    assert len(fig) == 1
    img = res.obs[res.obs["kind"] == "image"]
    x = np.array([img["x_mm"].min(), img["x_mm"].max()])
    y = np.array([img["y_mm"].min(), img["y_mm"].max()])
    n2 = (x[:, None] ** 2 + y[None, :] ** 2) / c["value"] ** 2  # normalised radius^2
    corner = np.sqrt(n2) * c["value"] * np.abs(k1["value"] * n2 + k2["value"] * n2**2) * 1e3
    largest = float(fig[0].text.split("largest ")[1].split(" µm")[0])
    assert largest == pytest.approx(corner.max(), abs=0.05)
