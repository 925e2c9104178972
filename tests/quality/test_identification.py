"""Snooping that says when it cannot tell two observations apart (issue 30)."""

from dataclasses import replace

import numpy as np
import pytest

import baarda
from baarda.bundle.bundle_model import BundleModel
from baarda.pipeline import adjust, snoop
from baarda.quality.statistics import analyse
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def clean():
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=8, pattern=5, seed=1))
    model = BundleModel(adjust(block))
    return block, model, analyse(model)


def planted(block, model, row, size_mdb, q):
    xy = block.image.xy_mm.copy()
    xy[model.image_row[row], "xy".index(model.component[row])] += size_mdb * q.mdb[row]
    return replace(block, image=replace(block.image, xy_mm=xy))


def _pair(model, q, tie):
    """An image component with an inseparable partner; tie: on a tie point (removing both
    leaves the point undetermined) or on a control point (removing both is possible)."""
    ctrl = set(np.asarray(model.point)[model.kind == "control"].tolist())
    for i in np.flatnonzero(q.controlled & (q.rho_max >= 0.9999) & (model.kind == "image")
                            & (q.redundancy_number > 0.3)):
        j = q.rho_partner[i]
        on_control = model.point[i] in ctrl
        if on_control != tie and model.kind[j] == "image" and model.point[j] == \
                model.point[i]:
            return int(i), int(j)
    raise AssertionError("no such pair")


def test_inseparable_rejection_is_identified_up_to_its_pair(clean):
    block, model, q = clean
    i, j = _pair(model, q, tie=True)
    qc = snoop(planted(block, model, i, 4.0, q))
    step = qc.run.log[0]
    assert step.action == "reject" and set(step.rows) | set(step.partners) == {i, j}
    assert abs(step.partner_rho[0]) > 0.9999 and not step.grouped
    text = qc.summary()
    assert "identified up to {" in text and "flagged: not separable" in text
    # the twin left behind is uncontrolled now, and the log says so in words
    other = step.partners[0]
    words = (f"the remaining {model.component[other]} of point {model.point[other]} on "
             f"photo {model.frame[other]} can no longer be checked")
    assert words in text and step.uncontrolled == (other,)
    entry = qc.to_dict()["rejection_log"][0]
    assert sorted(entry["identified_up_to"]) == sorted(
        [qc.model and t for t in step.group]) and entry["not_separable"]
    # the group cannot be rejected here (the point would be undetermined): flagged as well
    g = snoop(planted(block, model, i, 4.0, q), inseparable="group")
    assert not g.run.log[0].grouped and g.run.log[0].partners


def test_group_rejection_where_the_block_stays_determined(clean):
    block, model, q = clean
    i, j = _pair(model, q, tie=False)
    bad = planted(block, model, i, 4.0, q)
    one = snoop(bad)
    group = snoop(bad, inseparable="group")
    first = group.run.log[0]
    assert first.grouped and set(first.rows) | set(first.partners) == {i, j}
    assert "all rejected" in group.summary()
    # whichever holds the error, it is out, and the pair is not taken apart again
    assert not group.quality.active[i] and not group.quality.active[j]
    assert not any(s.action == "restore" and set(s.rows) & {i, j} for s in group.run.log)
    # snooping by Baarda's rule rejects one of the two (here the larger |w|) and flags the
    # other
    step = one.run.log[0]
    assert not step.grouped and {*step.rows, *step.partners} == {i, j}


def test_the_demo_names_the_absorbed_fifth_blunder():
    qc = baarda.snoop(baarda.read("examples/demo"))
    text = qc.summary()
    assert "point 005010: y on photos 02008, 03008" in text
    sep = qc.to_dict()["separability"]
    assert {"point": "005010", "component": "y", "frames": ["02008", "03008"]} in \
        sep["uncontrolled_components"]
    assert sep["uncontrolled"] == 16 and "005010" in sep["two_ray_points"]


@pytest.mark.parametrize("parquet", [False, True])
def test_the_observation_table_carries_rho_max_partner_and_msb(tmp_path, parquet):
    from baarda.io.result_folder import read_results
    from baarda.output.bundle_results import write_results

    qc = baarda.snoop(baarda.read("examples/demo"))
    write_results(tmp_path / "out", qc, parquet=parquet)
    df = read_results(tmp_path / "out").obs
    q, m = qc.quality, qc.model
    unit = np.where(m.kind == "image", 1e3, 1.0)
    t = np.flatnonzero(q.controlled)
    assert np.array_equal(df["rho_max"].to_numpy()[t], q.rho_max[t])
    assert np.allclose(df["msb"].to_numpy()[t], q.msb[t] * unit[t], rtol=1e-15)
    i = int(np.flatnonzero(q.controlled & (q.rho_max > 0.99))[0])
    j = int(q.rho_partner[i])
    assert df["rho_partner"].iloc[i] == (f"{m.kind[j]} photo {m.frame[j]} point {m.point[j]} "
                                         f"{m.component[j]}")
    assert (df["msb"].to_numpy()[t] >= df["mdb"].to_numpy()[t]).all()


def test_the_reports_show_the_inseparable_group_and_the_least_separable(clean, tmp_path):
    from baarda.io.result_folder import read_results
    from baarda.output.bundle_results import write_results
    from baarda.report.html_report import html_report
    from baarda.report.text_report import text_report

    block, model, q = clean
    i, _ = _pair(model, q, tie=True)
    qc = snoop(planted(block, model, i, 4.0, q))
    write_results(tmp_path / "out", qc)
    res = read_results(tmp_path / "out")
    text = text_report(res)
    log = text[text.index("SNOOPING LOG"):text.index("GROUP STATISTICS")]
    assert "identified up to {" in log and "can no longer be checked" in log
    assert "LEAST SEPARABLE" in text and "MSB/MDB" in text
    page = html_report(res)
    assert "identified up to {" in page and "Least separable" in page
    assert 'id="fig-msb_mdb"' in page
