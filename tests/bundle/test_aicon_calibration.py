"""The AICON close-range network adjusts as AICON 3D Studio did (issue 13 acceptance): the
camera model 'aicon' estimated as the protocol says, the scale bar as an observation, a free
network; counts, residual RMS, redundancy numbers, test values and the calibrated camera
against the protocol (example.htm).  The data (GPL-3.0) are read from ../shared/data."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baarda.io.aicon_protocol import read_protocol
from baarda.pipeline import adjust, assess, read

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / \
    "aicon_jaicov_closerange"
pytestmark = pytest.mark.skipif(not (SHARED / "example.htm").is_file(),
                                reason=f"AICON example (GPL-3.0, not in the repository) not "
                                f"found at {SHARED}")


@pytest.fixture(scope="module")
def protocol():
    return read_protocol(SHARED / "example.htm")


@pytest.fixture(scope="module")
def qc():
    block = read(SHARED)
    # start the estimated distortion at zero (A1, A2, B1, B2; A3, C1, C2 stay as AICON held
    # them): the self-calibration must find AICON's values
    coef = block.cameras.coefficients.copy()
    coef[:, [0, 1, 3, 4]] = 0.0
    cams = replace(block.cameras, coefficients=coef)
    res = adjust(replace(block, cameras=cams))
    return assess(res)


def test_counts_and_residuals(qc):
    res = qc.adjustment
    assert res.n_observations == 19945 and res.redundancy == 18804
    assert res.converged
    im = res.image_residuals[res.lin.w[:, 0] > 0]
    rms = np.sqrt(np.mean(im**2, axis=0))  # mm
    assert np.allclose(rms, [0.000418, 0.000369], rtol=0.02)  # protocol: rms vx, vy
    assert abs(res.sigma0 * 0.0005 - 0.000405) < 0.000405 * 0.01  # S0 a posteriori, mm


def test_redundancy_numbers_and_test_values(qc, protocol):
    model, q = qc.model, qc.quality
    po = protocol.observations
    key = {(str(i), p): k for k, (i, p) in enumerate(zip(po["image"].tolist(),
                                                          po["point"].tolist(), strict=True))}
    img = np.flatnonzero(model.kind == "image")
    rows = np.array([key[(model.frame[i], model.point[i])] for i in img])
    is_x = model.component[img] == "x"
    ref_r = np.where(is_x, po["rx"][rows], po["ry"][rows])
    ref_t = np.where(is_x, po["t1"][rows], po["t2"][rows])
    r = q.redundancy_number[img]
    assert np.mean(np.abs(r - ref_r) <= 0.01 + 1e-9) >= 0.995
    tau = np.abs(q.tau[img])
    ok = np.isfinite(tau)
    assert np.corrcoef(tau[ok], ref_t[ok])[0, 1] >= 0.999


def test_calibrated_camera_within_two_sigma_of_the_protocol(qc, protocol):
    res = qc.adjustment
    table = {r["parameter"]: r for r in res.camera_table()}
    for name, (value, std) in protocol.camera.items():
        row = table[name]
        if std is None:
            assert not row["estimated"]
            continue
        assert row["estimated"]
        assert abs(row["value"] - value) <= 2 * std, (name, row["value"], value, std)
        assert np.isclose(row["sigma"], std, rtol=0.05), (name, row["sigma"], std)


def test_point_standard_deviations_are_the_protocols_by_default(qc):
    """Issue 41: an AICON project is adjusted in AICON's own datum (inner constraints on
    the points) by default: every point's standard deviations equal AICON's (.obc sX, sY,
    sZ, printed to 1e-4 mm) to 5e-5 mm (with photo 1 held they differed by up to 0.021
    mm)."""
    from baarda.output.bundle_results import points_table

    assert qc.adjustment.block.settings.datum == "inner"
    t = points_table(qc.adjustment)
    obc = np.loadtxt(SHARED / "example.obc")
    ids = [str(int(v)) if float(v).is_integer() else repr(float(v)) for v in obc[:, 0]]
    aicon = dict(zip(ids, obc[:, 4:7], strict=True))  # mm
    ours = np.array([t.loc[t.point == p, ["sigma_X", "sigma_Y", "sigma_Z"]].to_numpy()[0]
                     for p in t.point]) * 1e3
    theirs = np.array([aicon[p] for p in t.point])
    assert len(t) == 150 and np.abs(ours - theirs).max() < 5e-5
