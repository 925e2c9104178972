"""BINGO with Pix4D's calibrated camera parameters: read (io/bingo.py), written
(output/bingo_files.py, `baarda convert --to bingo`); baarda's projection of the read block
is Pix4D's documented one (tests/io/pix4d_exports.py, written independently); round trips of
COLMAP's Maupertuis model and of a simulated block; bad input named by file, line and field.
No public Pix4D sample with a licence exists (tests/data/bingo_pix4d/README.md)."""

import json
import shutil
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import baarda
from baarda.block.camera_models import MODELS, apply_forward
from baarda.bundle.collinearity import project
from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.formats import detect
from baarda.output.bingo_files import write_bingo
from baarda.pipeline import with_approximations
from baarda.simulate.aerial import FlightPlan, simulate_block

sys.path.insert(0, str(Path(__file__).parent))
from pix4d_exports import sample_block, write_pix4d  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "tests" / "data" / "bingo_pix4d"
COLMAP = ROOT / "tests" / "data" / "colmap_maupertuis" / "sparse"


def baarda_projection(b, xyz: np.ndarray) -> np.ndarray:
    """baarda's image coordinates [mm] of ground points xyz (one per image observation) by
    the block's cameras (collinearity + the forward lens model)."""
    im, c = b.image, b.cameras
    cam = b.photos.camera[im.photo]
    n = project(b.photos.eo[im.photo], xyz, c.focal_mm[cam], np.zeros((len(cam), 2))) \
        / c.focal_mm[cam][:, None]
    out = n.copy()
    for k in range(len(c)):
        s = cam == k
        if c.model is not None and c.model[k] != "none":
            out[s] = apply_forward(MODELS[c.model[k]], n[s], c.coefficients[k:k + 1])[0]
    return c.principal_point_mm[cam] + c.focal_mm[cam][:, None] * out


def test_sample_projects_as_pix4d_documents():
    """The sample (written from Pix4D's descriptions by tests/io/pix4d_exports.py): read, two
    cameras (the second image has its own cx), and baarda's projection of the ground points
    gives the file's image coordinates to their 8 decimals (5e-9 mm); the tangential terms
    taken the other way round would be 1e-4 mm off."""
    assert detect(SAMPLE) == "bingo" and detect(SAMPLE / "proj_tp_bingo.txt") == "bingo"
    b = baarda.read(SAMPLE)
    assert (len(b.cameras), len(b.photos), len(b.image), len(b.points)) == (2, 3, 60, 20)
    assert b.photos.ids == ["IMG_0000", "IMG_0001", "IMG_0002"]
    assert b.cameras.pixel_mm.tolist() == [0.00158, 0.00158]
    assert b.cameras.coefficients[0].tolist() == [-0.12, 0.09, -0.02, -0.0007, 0.0011, 0.0]
    images, X = sample_block()
    xyz = X[[int(b.points.ids[j]) - 1001 for j in b.image.point]]
    err = np.abs(baarda_projection(b, xyz) - b.image.xy_mm).max()
    assert err <= 5.1e-9
    swapped = replace(b, cameras=replace(b.cameras, coefficients=b.cameras.coefficients[
        :, [0, 1, 2, 4, 3, 5]]))
    assert np.abs(baarda_projection(swapped, xyz) - b.image.xy_mm).max() > 1e-4
    assert b.settings.sigma_image_um == pytest.approx(1.58, rel=1e-12)  # 1 px


def test_sample_is_the_exporters(tmp_path):
    """tests/data/bingo_pix4d is what tests/io/pix4d_exports.py writes (its README)."""
    images, X = sample_block()
    write_pix4d(tmp_path, images, X)
    for f in SAMPLE.glob("proj_*.txt"):
        assert (tmp_path / f.name).read_bytes() == f.read_bytes()


def _same(a, b, rel: float = 1e-9) -> None:
    assert b.photos.ids == a.photos.ids
    assert np.abs(b.photos.eo - a.photos.eo).max() <= rel * np.abs(a.photos.eo).max()
    key = lambda blk: sorted(  # noqa: E731
        (blk.photos.ids[p], blk.points.ids[q], *blk.image.xy_mm[k])
        for k, (p, q) in enumerate(zip(blk.image.photo, blk.image.point, strict=True)))
    assert key(b) == key(a)
    ca, cb = a.photos.camera, b.photos.camera
    assert np.allclose(b.cameras.focal_mm[cb], a.cameras.focal_mm[ca], rtol=1e-14, atol=0)
    assert np.allclose(b.cameras.principal_point_mm[cb], a.cameras.principal_point_mm[ca],
                       rtol=0, atol=1e-14)


def test_round_trips(tmp_path):
    """The sample, COLMAP's Maupertuis model and a simulated aerial block with a lens and a
    principal point: written, read back, the same photos, orientations (1e-9 relative),
    observations exactly, cameras to 1e-14."""
    for k, a in enumerate([baarda.read(SAMPLE), baarda.read(COLMAP)]):
        notes = write_bingo(a, tmp_path / f"o{k}")
        assert any("no image sigmas" in n for n in notes)
        b = baarda.read(tmp_path / f"o{k}")
        _same(a, b)
        ka = np.zeros((len(a.cameras), 6))
        if a.cameras.coefficients is not None:
            ka[:, :a.cameras.coefficients.shape[1]] = a.cameras.coefficients
        assert np.allclose(b.cameras.coefficients[b.photos.camera], ka[a.photos.camera],
                           rtol=0, atol=1e-15)
    sim, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, pattern=3, seed=2))
    cams = replace(sim.cameras, principal_point_mm=np.array([[0.012, -0.008]]),
                   model=np.array(["brown_forward"], dtype=object),
                   coefficients=np.array([[-0.05, 0.01, 0.0, 1e-4, -2e-4, 1e-5]]),
                   pixel_mm=np.array([0.009]))
    sim = replace(sim, cameras=cams)
    notes = write_bingo(sim, tmp_path / "sim")
    assert any("control/check point(s)" in n for n in notes)
    b = baarda.read(tmp_path / "sim")
    _same(sim, b)
    assert np.allclose(b.cameras.coefficients, cams.coefficients, rtol=0, atol=1e-15)
    assert b.cameras.pixel_mm[0] == pytest.approx(0.009, rel=1e-15)


def test_a_lens_pix4d_cannot_hold(tmp_path):
    a = baarda.read(ROOT / "examples" / "demo")
    cams = replace(a.cameras, model=np.array(["brown"], dtype=object),
                   coefficients=np.array([[1e-5, 0, 0, 0, 0, 0, 0]]))
    a = with_approximations(replace(a, cameras=cams))
    with pytest.raises(ValueError, match="camera cam: model brown .* no Pix4D equivalent"):
        write_bingo(a, tmp_path)


def _copy(tmp_path: Path) -> Path:
    d = tmp_path / "b"
    shutil.copytree(SAMPLE, d)
    return d


def _edit(path: Path, edit) -> None:
    path.write_text("\n".join(edit(path.read_text().split("\n"))))


def _fails(capsys, path: Path, *expected: str) -> None:
    assert main(["convert", str(path), "-o", str(path.parent / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    for e in expected:
        assert e in err, err


def test_bad_input(tmp_path, capsys):
    """A truncated file (at a line end: an image lost; inside a line), a -99 missing, an
    unknown image, a non-number field, a camera record cut short, a rotation that is not
    one: exit 2 naming file, line and field."""
    bingo, cams = "proj_tp_bingo.txt", "proj_calibrated_camera_parameters.txt"
    d = _copy(tmp_path / "a")
    _edit(d / bingo, lambda s: s[:44] + [""])  # the last image's record gone
    _fails(capsys, d, bingo, "image IMG_0002.JPG of proj_calibrated_camera_parameters.txt "
           "(line 29) has no BINGO record: 1 of 3 images missing (a truncated file?)")
    d = _copy(tmp_path / "b")
    _edit(d / bingo, lambda s: s[:50] + [""])  # inside the last image, no -99
    _fails(capsys, d, f"{bingo}, line 50", "image IMG_0002 (line 45) is not ended by -99")
    d = _copy(tmp_path / "c")
    _edit(d / bingo, lambda s: s[:21] + s[22:])  # the first image's -99 gone
    _fails(capsys, d, f"{bingo}, line 22, column 'point'", "found 2 field(s) (a -99 "
           "missing before an image header?)")
    d = _copy(tmp_path / "d")
    _edit(d / bingo, lambda s: ["IMG_9999 " + s[0].split()[1]] + s[1:])
    _fails(capsys, d, f"{bingo}, line 1, column 'image'", "image IMG_9999 is not in "
           "proj_calibrated_camera_parameters.txt (3 images): an unknown image")
    d = _copy(tmp_path / "e")
    _edit(d / bingo, lambda s: s[:1] + [s[1].split()[0] + " 1.x5 2"] + s[2:])
    _fails(capsys, d, f"{bingo}, line 2, column 'x'", "'1.x5' is not a number")
    d = _copy(tmp_path / "f")
    _edit(d / cams, lambda s: s[:-3] + [""])
    _fails(capsys, d, f"{cams}, line 36", "28 record lines: 10 per image expected (a "
           "truncated file?)")
    d = _copy(tmp_path / "g")
    _edit(d / cams, lambda s: s[:15] + [" ".join(str(2 * float(v)) for v in s[15].split())]
          + s[16:])
    _fails(capsys, d, f"{cams}, line 16, column 'R'", "image IMG_0000.JPG: R is not a "
           "rotation")
    d = _copy(tmp_path / "h")
    (d / cams).unlink()
    _fails(capsys, d, "0 '*_calibrated_camera_parameters.txt' files beside "
           "proj_tp_bingo.txt: one expected")


@pytest.mark.slow
def test_readjusted_gives_the_same_sigma0(tmp_path):
    """Maupertuis as BINGO adjusts (--sigma-px 1 --calibrate none) to COLMAP's redundancy
    and sigma0 (1e-6); its result folder converted to BINGO and re-adjusted too."""
    def adjust(path, out):
        assert main(["adjust", str(path), "--sigma-px", "1", "--calibrate", "none", "-o",
                     str(out), "-q"]) in (0, 5)
        s = json.loads((out / "summary.json").read_text())
        return s["redundancy"], s["sigma0"]

    red, s0 = adjust(COLMAP, tmp_path / "colmap")
    assert red == 3566 and s0 == pytest.approx(0.4754116, rel=1e-6)
    assert main(["convert", str(COLMAP), "--to", "bingo", "-o", str(tmp_path / "b"),
                 "-q"]) == 0
    assert adjust(tmp_path / "b", tmp_path / "r1")[0] == red
    assert adjust(tmp_path / "b", tmp_path / "r1")[1] == pytest.approx(s0, rel=1e-6)
    assert main(["convert", str(tmp_path / "colmap"), "--to", "bingo", "-o",
                 str(tmp_path / "c"), "-q"]) == 0
    assert (tmp_path / "c" / "rejected.csv").read_text().startswith("photo,point,component")
    r, s = adjust(tmp_path / "c", tmp_path / "r2")
    assert r == red and s == pytest.approx(s0, rel=1e-6)


def test_demo_as_bingo_with_its_control_adjusts_as_the_demo(tmp_path):
    """The demo written as BINGO (no control in the format) and read back with `--control`
    its ground_points.csv and `--sigma-image-um 5` adjusts to the demo's redundancy 172 and
    sigma0 1.4629371 (1e-6)."""
    demo = ROOT / "examples" / "demo"
    assert main(["convert", str(demo), "--to", "bingo", "-o", str(tmp_path / "b"),
                 "-q"]) == 0
    assert main(["adjust", str(tmp_path / "b"), "--control", str(demo / "ground_points.csv"),
                 "--sigma-image-um", "5", "-o", str(tmp_path / "r"), "-q"]) in (0, 5)
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["redundancy"] == 172 and s["sigma0"] == pytest.approx(1.4629371, rel=1e-6)


def test_offset_is_added_to_the_camera_positions(tmp_path):
    """Pix4D's camera file is in the output frame less `*_offset.xyz` (EasyIDP's example:
    t 21.549 + offset 368009 = the image position 368030.549): X0 = t + offset, noted."""
    d = _copy(tmp_path)
    (d / "proj_offset.xyz").write_text("368009.000 3955854.000 97.000")  # no line end
    a, b = baarda.read(SAMPLE), baarda.read(d)
    assert np.array_equal(b.photos.eo[:, :3], a.photos.eo[:, :3] + [368009.0, 3955854.0, 97.0])
    assert np.array_equal(b.photos.eo[:, 3:], a.photos.eo[:, 3:])
    assert any("the offset [368009.0, 3955854.0, 97.0] of proj_offset.xyz" in n
               for n in b.notes)
    (d / "proj_offset.xyz").write_text("368009.000 3955854.000\n")
    with pytest.raises(ProjectError, match="proj_offset.xyz, line 1, column 'offset': one "
                       "line 'X Y Z' expected"):
        baarda.read(d)


def test_headers_without_a_sensor_size(tmp_path):
    """BINGO's own image.dat headers ('photo camera') have no sensor size: the pixel is
    --pixel-mm (default 1 µm, noted); with the sample's 1.58 µm the block is the sample's.
    With a sensor size in the headers --pixel-mm is refused."""
    d = _copy(tmp_path)
    _edit(d / "proj_tp_bingo.txt", lambda s: [x.split()[0] + " H" if x.startswith("IMG")
                                              else x for x in s])
    b = baarda.read(d)
    assert b.cameras.pixel_mm.tolist() == [0.001, 0.001]
    assert any("no sensor size in an image header: pixel 0.001 mm" in n for n in b.notes)
    a, c = baarda.read(SAMPLE), baarda.read(d, pixel_mm=0.00158)
    _same(a, c)
    assert np.array_equal(c.cameras.focal_mm, a.cameras.focal_mm)
    with pytest.raises(ProjectError, match="--pixel-mm does not apply: the BINGO headers"):
        baarda.read(SAMPLE, pixel_mm=0.002)


def test_sample_adjusts_to_its_rounding(tmp_path):
    """The sample's image coordinates are Pix4D projections rounded to 1e-8 mm: adjusted as
    read (cameras held, 1 px = 1.58 µm) its sigma0 is that rounding's, 1.5e-6 (rounding
    noise 1e-8 / sqrt(12) mm over 1.58 µm), with redundancy 2 x 60 - (3 x 6 + 20 x 3 - 7) =
    49: baarda's model of the files is Pix4D's."""
    assert main(["adjust", str(SAMPLE), "--calibrate", "none", "-o", str(tmp_path / "r"),
                 "-q"]) in (0, 5)
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["redundancy"] == 49
    assert 0.5e-6 < s["sigma0"] < 3e-6
