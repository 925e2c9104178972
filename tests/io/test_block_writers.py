"""`baarda convert --to colmap|bal|opensfm|aicon` (output/block_formats.py): a Block written through
the registry's writer, read back as the same block; a result folder converted and adjusted
again gives the result's sigma0 (1e-6).  Data: COLMAP's Maupertuis model (shared data)."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import baarda
from baarda.cli import main
from baarda.io.formats import spec
from baarda.output.block_formats import write_colmap_block
from baarda.output.project_files import write_project

DATA = Path(__file__).resolve().parents[1] / "data"
if not DATA.is_dir():
    DATA = Path("/work/shared/data")
COLMAP = DATA / "colmap_maupertuis" / "sparse"
DEMO = Path(__file__).resolve().parents[2] / "examples" / "demo"
needs_colmap = pytest.mark.skipif(not COLMAP.is_dir(), reason="the shared COLMAP Maupertuis "
                                  "model is not there (/work/shared/data/colmap_maupertuis)")
READ_BACK = {"colmap": "", "bal": "problem.txt", "opensfm": "", "aicon": ""}


def _observations(b):
    """The image observations (point coordinates, x, y) sorted: the points named by their
    coordinates (BAL renumbers them)."""
    xyz = np.round(b.points.xyz, 9)
    return np.array(sorted((*xyz[q], *b.image.xy_mm[k]) for k, q in enumerate(b.image.point)))


@needs_colmap
@pytest.mark.parametrize("to", list(READ_BACK))
def test_round_trip(tmp_path, to):
    """Written through the registry and read back: the same photos, orientations (1e-9
    relative: 1e-15 for COLMAP and OpenSfM, 1e-12 for BAL's rotation vectors), observations
    (1e-15 mm: COLMAP adds and removes the image centre in pixels, OpenSfM normalises) and
    focal lengths; the notes say what was dropped."""
    a = baarda.read(COLMAP)
    notes = spec(to).writes(a, tmp_path)
    b = baarda.read(tmp_path / READ_BACK[to])
    if to == "bal":  # one camera per photo, photos numbered
        assert b.photos.ids == [str(i) for i in range(4)] and len(b.cameras) == 4
        assert any("one camera per photo" in n and "no principal point" in n for n in notes)
    elif to == "aicon":  # ids are numbers: COLMAP's image names '03' ... renumbered
        assert b.photos.ids == ["1", "2", "3", "4"] and b.points.ids == a.points.ids
        assert any("photo ids renumbered" in n for n in notes)
        assert np.array_equal(b.image.sigma_xy, a.image.sigma_xy)  # sx, sy [mm] written
        assert np.abs(b.points.xyz - a.points.xyz).max() <= 1e-15 * np.abs(a.points.xyz).max()
    else:
        assert b.photos.ids == a.photos.ids
        assert any("no image sigmas" in n for n in notes)
    assert np.abs(b.photos.eo - a.photos.eo).max() <= 1e-9 * np.abs(a.photos.eo).max()
    oa, ob = _observations(a), _observations(b)
    assert oa.shape == ob.shape == (3350, 5)
    assert np.abs(oa - ob).max() <= 1e-15
    assert np.allclose(b.cameras.focal_mm, a.cameras.focal_mm[0], rtol=1e-15, atol=0)


def _lens(block, coef, pp=(0.0, 0.0)):
    """`block` with a brown_forward camera (k1, k2, k3, p1, p2, a) and principal point."""
    c = block.cameras
    return replace(block, cameras=replace(c, model=np.array(["brown_forward"], dtype=object),
                                          coefficients=np.array([coef], float),
                                          principal_point_mm=np.array([pp], float)))


@needs_colmap
@pytest.mark.parametrize("coef, model", [
    ([0.0, 0.0, 0.0, 0.0, 0.0, 0.0], "SIMPLE_PINHOLE"),
    ([-0.1, 0.0, 0.0, 0.0, 0.0, 0.0], "SIMPLE_RADIAL"),
    ([-0.1, 0.05, 0.0, 0.0, 0.0, 0.0], "RADIAL"),
    ([-0.1, 0.05, 0.0, 0.002, -0.003, 0.0], "OPENCV"),
    ([-0.1, 0.05, 0.02, 0.002, -0.003, 0.0], "FULL_OPENCV")])
def test_colmap_camera_models(tmp_path, coef, model):
    """A brown_forward camera with a principal point goes out as the smallest COLMAP model
    that holds it and reads back with the same coefficients (1e-15) and principal point
    (1e-15 mm): the writer is the reader's inverse, decentring signs included."""
    a = _lens(baarda.read(COLMAP), coef, (0.012, -0.021))
    write_colmap_block(a, tmp_path)
    assert (tmp_path / "cameras.txt").read_text().split("\n")[3].split()[1] == model
    b = baarda.read(tmp_path)
    got = np.zeros(6) if b.cameras.coefficients is None else b.cameras.coefficients[0]
    assert np.abs(got[:5] - coef[:5]).max() <= 1e-15
    assert np.abs(b.cameras.principal_point_mm - a.cameras.principal_point_mm).max() < 1e-15
    assert np.abs(_observations(b) - _observations(a)).max() <= 1e-15


def _adjust(path, out, sigma=("--sigma-px", "1")) -> dict:
    assert main(["adjust", str(path), *sigma, "--calibrate", "none", "-o", str(out),
                 "-q"]) in (0, 5)
    return json.loads((out / "summary.json").read_text())


@pytest.mark.slow
@needs_colmap
def test_colmap_lens_adjusts_as_written(tmp_path):
    """The decentring signs and the aspect checked by the adjustment, independently of the
    reader: a block with OpenCV's full lens, a principal point and an aspect adjusts as a
    native project and as its COLMAP model (the aspect as fy = fx (1 + a)) to the same
    redundancy and sigma0 (1e-6); with p1, p2 swapped in the file sigma0 differs."""
    a = _lens(baarda.read(COLMAP), [-0.1, 0.05, 0.02, 0.002, -0.003, 0.004], (0.012, -0.021))
    write_project(a, tmp_path / "native")
    notes = write_colmap_block(a, tmp_path / "colmap")
    assert any("fy = fx (1 + a)" in n for n in notes)
    first = _adjust(tmp_path / "native", tmp_path / "r1", ("--sigma-image-um", "1"))
    second = _adjust(tmp_path / "colmap", tmp_path / "r2")
    assert second["redundancy"] == first["redundancy"] == 3566
    assert second["sigma0"] == pytest.approx(first["sigma0"], rel=1e-6)
    # the same block read from the file with the decentring terms swapped: another sigma0
    line = (tmp_path / "colmap" / "cameras.txt").read_text().split("\n")
    v = line[3].split()
    v[10], v[11] = v[11], v[10]
    line[3] = " ".join(v)
    (tmp_path / "colmap" / "cameras.txt").write_text("\n".join(line))
    third = _adjust(tmp_path / "colmap", tmp_path / "r3")
    assert abs(third["sigma0"] / first["sigma0"] - 1) > 1e-3


@pytest.mark.slow
@needs_colmap
def test_result_converted_and_adjusted_again(tmp_path):
    """Acceptance (issue 38): `baarda convert RESULT --to colmap|bal|opensfm|aicon` re-read
    and re-adjusted (--sigma-px 1, AICON's sigmas in its file; --calibrate none) gives the
    result's redundancy and sigma0 (1e-6)."""
    first = _adjust(COLMAP, tmp_path / "res")
    assert first["redundancy"] == 3566
    assert first["sigma0"] == pytest.approx(0.4754116, rel=1e-6)
    for to, name in READ_BACK.items():
        assert main(["convert", str(tmp_path / "res"), "--to", to, "-o", str(tmp_path / to),
                     "-q"]) == 0
        # AICON holds the image sigmas (mm): no --sigma-px
        again = _adjust(tmp_path / to / name, tmp_path / f"{to}_again",
                        () if to == "aicon" else ("--sigma-px", "1"))
        assert again["redundancy"] == first["redundancy"], to
        assert again["sigma0"] == pytest.approx(first["sigma0"], rel=1e-6), to


@pytest.mark.slow
def test_demo_result_goes_out_without_its_rejections(tmp_path, capsys):
    """The demo (control and check points, 4 observations rejected by data snooping) as
    COLMAP, BAL and AICON: the adjusted block without the rejected observations (272 of 276), the
    control written as tie points (noted); OpenSfM refuses its height-only control points
    (exit 2, naming the point)."""
    res = tmp_path / "res"
    assert main(["adjust", str(DEMO), "--snoop", "-o", str(res), "-q"]) == 0
    for to, name in READ_BACK.items():
        code = main(["convert", str(res), "--to", to, "-o", str(tmp_path / to)])
        out = capsys.readouterr()
        if to == "opensfm":
            assert code == 2 and "OpenSfM GCPs need a horizontal position" in out.err
            continue
        assert code == 0 and "30 control/check point(s) written as tie points" in out.err
        b = baarda.read(tmp_path / to / name)
        assert len(b.image) == 276 - 4 and len(b.photos) == 32
        assert (tmp_path / to / "rejected.csv").read_text().count("\n") == 1 + 4


@needs_colmap
@pytest.mark.parametrize("to", ["colmap", "bal", "aicon"])
def test_a_lens_the_format_cannot_hold_is_refused(tmp_path, capsys, to):
    """A backward Brown lens (baarda's `brown`) has no COLMAP, BAL or AICON terms: `convert`
    exits 2 naming the camera and writes no model files."""
    a = baarda.read(COLMAP)
    c = a.cameras
    a = replace(a, cameras=replace(c, model=np.array(["brown"], dtype=object),
                                   coefficients=np.array([[1e-5, 0, 0, 0, 0, 0, 0]])))
    write_project(a, tmp_path / "native")
    assert main(["convert", str(tmp_path / "native"), "--to", to, "-o",
                 str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"camera {c.ids[0]}: model brown has no" in err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").glob("*.txt"))


AICON = Path(__file__).resolve().parents[3] / "shared" / "data" / \
    "aicon_jaicov_closerange" / "example.phc"  # as tests/io/test_aicon.py finds it


@pytest.mark.skipif(not AICON.is_file(), reason="the AICON example (GPL-3.0, shared data) is "
                    "not there")
def test_aicon_project_round_trip(tmp_path):
    """AICON's example (lens model aicon with R0, a scale bar, per-axis sigmas) written by
    the Block writer reads back as the same block: ids, cameras (terms, R0, c, principal
    point, free parameters) and observations with their sigmas exactly, orientations and
    points to 1e-15 relative (mm -> m), the scale bar; the principal point is not noted as
    dropped (AICON holds it)."""
    a = baarda.read(AICON)
    notes = spec("aicon").writes(a, tmp_path)
    assert not any(n.startswith("principal point") for n in notes)
    b = baarda.read(tmp_path)
    assert (b.photos.ids, b.points.ids, b.cameras.ids) == (a.photos.ids, a.points.ids,
                                                           a.cameras.ids)
    assert np.array_equal(b.cameras.coefficients, a.cameras.coefficients)
    assert np.array_equal(b.cameras.constants, a.cameras.constants)
    assert np.array_equal(b.cameras.focal_mm, a.cameras.focal_mm)
    assert np.array_equal(b.cameras.principal_point_mm, a.cameras.principal_point_mm)
    assert b.settings.calibration_free == a.settings.calibration_free
    assert np.array_equal(b.image.xy_mm, a.image.xy_mm)
    assert np.array_equal(b.image.sigma_xy, a.image.sigma_xy)
    assert np.abs(b.photos.eo - a.photos.eo).max() <= 1e-15 * np.abs(a.photos.eo).max()
    assert np.abs(b.points.xyz - a.points.xyz).max() <= 1e-15 * np.abs(a.points.xyz).max()
    assert b.distances.ids == a.distances.ids == ["Scalebar"]
    assert np.allclose(b.distances.length_m, a.distances.length_m, rtol=1e-15, atol=0)


@pytest.mark.slow
def test_opensfm_result_with_control_converted_and_adjusted_again(tmp_path):
    """A simulated block with 3D control, check points and GNSS (test_opensfm's), adjusted as
    a native project: `baarda convert RESULT --to opensfm` keeps the control's given
    coordinates (FormatSpec.control) and the GNSS positions, and re-read (--sigma-px 5: the
    project's 5 µm in 1 µm pixels; --check-gcp the check points) and re-adjusted gives the
    result's redundancy and sigma0 (1e-6)."""
    from baarda.simulate.aerial import FlightPlan, simulate_block

    b, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=40.0,
                                     check_points=3, height_chains=0, gnss_sigma_m=0.1,
                                     seed=11))
    write_project(b, tmp_path / "native")
    first = _adjust(tmp_path / "native", tmp_path / "res", ())
    assert main(["convert", str(tmp_path / "res"), "--to", "opensfm", "-o",
                 str(tmp_path / "osfm"), "-q"]) == 0
    checks = [p for p, r in zip(b.points.ids, b.points.role, strict=True) if r == "check"]
    again = _adjust(tmp_path / "osfm", tmp_path / "again",
                    ("--sigma-px", "5", "--check-gcp", ",".join(checks)))
    assert again["redundancy"] == first["redundancy"] == 106
    assert again["sigma0"] == pytest.approx(first["sigma0"], rel=1e-6)


def test_convert_help_lists_every_writer(capsys):
    """The help of --to is made of TARGETS, and every target but the native project is a
    format whose registry entry has a writer."""
    from baarda.cli.convert import TARGETS, _spec

    with pytest.raises(SystemExit):
        main(["convert", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for to, files in TARGETS.items():
        assert f"{to} ({' '.join(files.split())})" in text
        assert to == "project" or _spec(to).writer is not None
    assert {"colmap", "bal", "opensfm", "aicon"} <= set(TARGETS)
