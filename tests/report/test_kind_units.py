"""Every number of a kind is shown in the unit the result folder states for that kind
(issue 37, bugs 3 and 4): the HTML report's weakest tables label IMU MDBs in the project's
angle unit (mgon here, as observations.csv writes them), and the variance components'
sigmas are in observations.csv's units in summary.json, the HTML table and the text report.
"""

import json
import re

import numpy as np
import pandas as pd
import pytest
from gnss_blocks import with_gnss
from htmlrows import table_rows

from baarda.io.result_folder import read_results
from baarda.output.bundle_results import write_results
from baarda.pipeline import prepare, snoop_with_variance_components
from baarda.report.html_report import html_report
from baarda.report.text_report import text_report
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def gnss_run(tmp_path_factory):
    """A simulated block in gon with GNSS positions and IMU attitudes (1e-4 rad = 6.366
    mgon), its variance components estimated and snooped, written and reported."""
    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=5, seed=4))
    assert block.settings.angle_unit == "gon"
    qc, _ = snoop_with_variance_components(prepare(with_gnss(block, truth, sigma_rad=1e-4)))
    out = tmp_path_factory.mktemp("kind_units") / "out"
    write_results(out, qc)
    res = read_results(out)
    obs = pd.read_csv(out / "observations.csv", dtype={"photo": str, "point": str},
                      keep_default_na=False, na_values=[""])
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    return res, obs, summary, html_report(res), text_report(res)


def test_imu_mdb_in_the_weakest_tables_has_the_files_unit(gnss_run):
    """Bug 3: the unit column of the weakest tables was schema.UNITS ('mrad' for IMU) while
    the values are observations.csv's, in mgon: a factor 63.7 for the reader."""
    res, obs, summary, html, _ = gnss_run
    assert summary["units"]["imu"] == "mgon"
    rows = table_rows(_after(html, "largest MDB (per kind)</h3>"), "t")
    imu = [cells for _, cells in rows if cells[0] == "imu"]
    assert imu, [cells[0] for _, cells in rows]
    for kind, unit in (("imu", "mgon"), ("image", "µm"), ("gnss", "m")):
        shown = [cells for _, cells in rows if cells[0] == kind]
        assert shown and {cells[6] for cells in shown} == {unit}, (kind, shown)
    # the largest IMU MDB shown is observations.csv's largest (in mgon: about 4.1 sigma)
    tested = obs[(obs["kind"] == "imu") & ~obs["rejected"].astype(bool) & obs["w"].notna()]
    assert float(imu[0][7]) == pytest.approx(tested["mdb"].max(), rel=1e-3)
    assert 20 < float(imu[0][7]) < 60  # mgon (1e-4 rad = 6.37 mgon, MDB ~ 4-8 sigma)


def _after(html: str, heading: str) -> str:
    """The first table after `heading`, as a table with the id 't'."""
    part = html[html.index(heading):]
    return part[:part.index("</table>") + 8].replace("<table", '<table id="t"', 1)


def _vc(summary: dict) -> dict[str, dict]:
    return {c["group"]: c for c in summary["variance_components"]}


def test_variance_component_sigmas_in_the_units_of_observations_csv(gnss_run):
    """Bug 4: summary.json and the HTML table gave the image sigmas in mm, IMU in rad,
    while observations.csv and the text report give µm and mgon."""
    res, obs, summary, html, text = gnss_run
    vc = _vc(summary)
    for group, kind, unit in (("image", "image", "µm"), ("imu", "imu", "mgon"),
                              ("gnss Z", "gnss", "m")):
        c = vc[group]
        sel = (obs["kind"] == kind) & ((obs["component"] == "Z") if kind == "gnss" else True)
        assert c["unit"] == unit
        # observations.csv's sigmas are those the tests used: the estimated ones
        assert c["sigma_estimated"] == pytest.approx(
            float(np.median(obs.loc[sel, "sigma"])), rel=1e-9), group
    assert vc["image"]["sigma_apriori"] == pytest.approx(5.0)  # µm, the simulated sigma
    assert vc["imu"]["sigma_apriori"] == pytest.approx(1e-4 * 200e3 / np.pi)  # mgon
    # the text report says the same numbers in the same units
    for group in ("image", "imu"):
        c = vc[group]
        assert re.search(rf"\b{group}: n {c['n']}, .*sigma a priori "
                         rf"{c['sigma_apriori']:.4g} {c['unit']}", text), group
    # the HTML table: the unit beside the sigma
    rows = {cells[0]: cells for _, cells in table_rows(html, "variance-components")}
    for group in ("image", "imu", "gnss Z"):
        cells = rows[group]
        assert float(cells[3]) == pytest.approx(vc[group]["sigma_apriori"], rel=1e-3)
        assert cells[4] == vc[group]["unit"]
        assert float(cells[-2]) == pytest.approx(vc[group]["sigma_estimated"], rel=1e-3)
