"""Self-calibration shared by a group: per camera (default) or per camera and strip
(`[calibration] group = "strip"`, `--calibration-group strip`; issue 13)."""

from dataclasses import replace

import numpy as np
import pytest

from baarda.block.camera import cameras_per_strip
from baarda.block.camera_models import get_model, invert
from baarda.cli import main
from baarda.io.project import read_project
from baarda.output.project_files import write_project
from baarda.pipeline import adjust, read
from baarda.simulate.aerial import FlightPlan, simulate_block

K1 = 3e-8  # mm^-2: strip 2's lens, 30 µm radial distortion at 100 mm


@pytest.fixture(scope="module")
def block():
    """Three strips, 5x5 points per photo; the camera on Brown's model with k1 estimated;
    strip 2 photographed through a lens with radial distortion K1 (its observations
    distorted by the model's inverse), the others without."""
    b, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, pattern=5, relief_m=150.0,
                                     seed=8))
    strip = np.asarray(b.photos.strip, dtype=object)
    second = sorted(set(strip.tolist()))[1]
    rows = strip[b.image.photo] == second
    pp = b.cameras.principal_point_mm[0]
    coef = np.zeros(7)
    coef[0] = K1
    xy = b.image.xy_mm.copy()
    xy[rows] = pp + invert(get_model("brown"), xy[rows] - pp, coef, None)
    cams = replace(b.cameras, model=np.array(["brown"], dtype=object),
                   coefficients=np.zeros((1, 7)))
    return replace(b, image=replace(b.image, xy_mm=xy), cameras=cams,
                   settings=replace(b.settings, calibration_free=(("k1",),))), second


def _k1(result):
    return {r["camera"]: (r["value"], r["sigma"]) for r in result.camera_table()
            if r["parameter"] == "k1"}


def test_per_strip_recovers_each_strips_distortion(block):
    b, second = block
    shared = adjust(b)
    per = adjust(cameras_per_strip(b))
    assert len(per.block.cameras) == 3 and per.problem.calibration.n == 3
    assert per.redundancy == shared.redundancy - 2
    for cid, (value, sigma) in _k1(per).items():
        expected = K1 if cid.endswith(f"/{second}") else 0.0
        assert abs(value - expected) < 3 * sigma, (cid, value, expected, sigma)
        assert sigma < 0.2 * K1  # each strip's k1 is well determined
    (value, sigma), = _k1(shared).values()
    assert abs(value - K1 / 3) < 0.3 * K1  # the shared one is a compromise
    assert per.sigma0 < shared.sigma0


def test_project_toml_and_command_line_agree(block, tmp_path):
    b, _ = block
    write_project(b, tmp_path / "p")
    toml = tmp_path / "p" / "project.toml"
    text = toml.read_text()
    toml.write_text(text + "\n[calibration]\ngroup = \"strip\"\n")
    raw = read_project(tmp_path / "p")  # as the files give it; the pipeline splits
    assert raw.settings.calibration_group == "strip" and len(raw.cameras) == 1
    a = read(tmp_path / "p")
    assert len(a.cameras) == 3 and all("/" in c for c in a.cameras.ids)
    toml.write_text(text)
    c = read(tmp_path / "p", calibration_group="strip")
    assert a.cameras.ids == c.cameras.ids and np.array_equal(a.photos.camera, c.photos.camera)
    assert main(["adjust", str(tmp_path / "p"), "--calibration-group", "strip", "-o",
                 str(tmp_path / "out"), "-q"]) == 0
    cams = (tmp_path / "out" / "cameras.csv").read_text()
    assert cams.count("/") >= 3
    toml.write_text(text + "\n[calibration]\ngroup = \"photo\"\n")
    assert main(["adjust", str(tmp_path / "p"), "-o", str(tmp_path / "bad")]) == 2


def test_calibration_group_camera_overrides_project_toml(block, tmp_path):
    """`baarda.read(project, calibration_group="camera")` and `--calibration-group camera`
    override project.toml's group = "strip" (issue 28: the per-strip cameras stayed)."""
    b, _ = block
    write_project(b, tmp_path / "p")
    toml = tmp_path / "p" / "project.toml"
    toml.write_text(toml.read_text() + "\n[calibration]\ngroup = \"strip\"\n")
    assert len(read(tmp_path / "p").cameras) == 3
    one = read(tmp_path / "p", calibration_group="camera")
    assert len(one.cameras) == 1 and one.cameras.ids == b.cameras.ids
    assert main(["adjust", str(tmp_path / "p"), "--calibration-group", "camera", "-o",
                 str(tmp_path / "out"), "-q"]) == 0
    assert "/" not in (tmp_path / "out" / "cameras.csv").read_text()
