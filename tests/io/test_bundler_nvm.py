"""Bundler v0.3 and VisualSFM NVM_V3: read (io/bundler.py, io/nvm.py), written
(output/sfm_files.py, `baarda convert --to`), checked against COLMAP's Maupertuis model
written in both formats by another writer (tests/io/sfm_exports.py: pycolmap and the
formats' published conventions)."""

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import baarda
from baarda.block.camera_models import MODELS
from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.formats import detect
from baarda.io.nvm import read_nvm
from baarda.output.sfm_files import write_bundler, write_nvm

sys.path.insert(0, str(Path(__file__).parent))
from sfm_exports import export_bundler, export_nvm  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "data"
if not DATA.is_dir():
    DATA = Path("/work/shared/data")
COLMAP = DATA / "colmap_maupertuis" / "sparse"


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    d = tmp_path_factory.mktemp("sfm")
    return export_bundler(COLMAP, d / "bundler"), export_nvm(COLMAP, d / "model.nvm")


def _observations(b):
    """The image observations as a set: (photo id, point coordinates, x, y); the points are
    named by their coordinates (the formats renumber them)."""
    xyz = np.round(b.points.xyz, 9)
    return sorted((b.photos.ids[p], *xyz[q], *b.image.xy_mm[k])
                  for k, (p, q) in enumerate(zip(b.image.photo, b.image.point, strict=True)))


def test_detected_and_read_as_colmap_has_it(exports):
    bundle, nvm = exports
    assert detect(bundle) == "bundler" and detect(bundle.parent) == "bundler"
    assert detect(nvm) == "nvm"
    ref = baarda.read(COLMAP)
    for path in exports:
        b = baarda.read(path)
        assert b.summary().split(":")[1] == ref.summary().split(":")[1]  # 4 photos, 3350 ...
        assert [len(x) for x in (b.photos, b.image, b.points)] == [4, 3350, 1039]
        order = [ref.photo_index[p] for p in b.photos.ids]
        # COLMAP's text file has the quaternions to 6 digits, pycolmap normalises them,
        # baarda's COLMAP reader too but by another route: the EO agree to 1e-5
        assert np.abs(b.photos.eo - ref.photos.eo[order]).max() < 1e-5
        # the same observations (x - cx, cy - y with cx, cy at the image centre): to 1e-12 mm
        a, r = np.array([o[1:] for o in _observations(b)]), \
            np.array([o[1:] for o in _observations(ref)])
        assert np.abs(a - r).max() < 1e-12
    notes = " ".join(baarda.read(bundle).notes)
    assert "no principal point" in notes and "5 repeated view(s)" in notes


@pytest.mark.parametrize("writer", [write_bundler, write_nvm])
def test_round_trip(exports, tmp_path, writer):
    """Each writer's file read back: orientations to 1e-9 relative (here 1e-15),
    observations exactly, the points' coordinates exactly."""
    for path in (*exports, COLMAP):
        a = baarda.read(path)
        notes = writer(a, tmp_path / "out")
        assert any("no principal point" in n for n in notes)
        b = baarda.read(tmp_path / "out" / ("model.nvm" if writer is write_nvm else ""))
        assert b.photos.ids == a.photos.ids
        assert np.abs(b.photos.eo - a.photos.eo).max() <= 1e-9 * np.abs(a.photos.eo).max()
        assert _observations(b) == _observations(a)
        assert np.array_equal(b.cameras.focal_mm, a.cameras.focal_mm)


def test_nvm_distortion_is_on_the_measured_point(tmp_path):
    """VisualSFM's r: undistorted = m (1 + r |m|^2 / f^2) on the measured m (pixels); baarda's
    backward ``brown`` with k1 = r / c^2 gives the same ideal point."""
    f, r, px = 1500.0, -0.12, 0.001
    nvm = tmp_path / "d.nvm"
    nvm.write_text(f"NVM_V3\n\n1\na.jpg {f} 1 0 0 0 0 0 0 {r} 0\n1\n0 0 10 1 2 3 1 0 5 "
                   "400.0 -300.0\n\n0\n")
    b = read_nvm(nvm, pixel_mm=px)
    assert b.cameras.model[0] == "brown"
    m = np.array([400.0, -300.0])
    u = b.image.xy_mm  # (x, -y) px
    coef = b.cameras.coefficients[:1]
    delta = MODELS["brown"].terms(u, coef, np.zeros((1, 0)))[0]
    ideal = (u + delta)[0] / px
    expected = m * (1 + r * (m @ m) / f ** 2) * [1, -1]
    assert np.allclose(ideal, expected, rtol=1e-13)
    # and back: the writer gives r again
    write_nvm(b, tmp_path / "w")
    assert float((tmp_path / "w" / "model.nvm").read_text().split("\n")[3].split()[9]) == \
        pytest.approx(r, rel=1e-14)


def test_nvm_several_models(exports, tmp_path):
    _, nvm = exports
    text = nvm.read_text().rstrip().rsplit("\n", 1)[0]  # without the closing 0
    body = text.split("\n", 2)[2]  # without the header and its blank line
    two = tmp_path / "two.nvm"
    two.write_text(text + "\n" + body + "\n0\n")
    b = baarda.read(two)
    assert any("the file has 2 models; model 0 read" in n for n in b.notes)
    assert len(read_nvm(two, model=1).image) == 3350
    with pytest.raises(ProjectError, match="model 2 asked for, the file has 2"):
        read_nvm(two, model=2)
    assert main(["convert", str(two), "--model", "1", "-o", str(tmp_path / "o1"), "-q"]) == 0
    assert main(["convert", str(COLMAP), "--model", "1", "-o", str(tmp_path / "o2"),
                 "-q"]) == 2


def _fails(capsys, path, *expected):
    """`baarda convert` exits 2 naming the file, the line and what was expected."""
    assert main(["convert", str(path), "-o", str(path.parent / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    for e in expected:
        assert e in err, err
    return err


def _bundler(tmp_path, exports, edit) -> Path:
    lines = exports[0].read_text().split("\n")
    d = tmp_path / "bad"
    d.mkdir(parents=True)
    (d / "bundle.out").write_text("\n".join(edit(lines)))
    (d / "list.txt").write_text(exports[0].with_name("list.txt").read_text())
    return d / "bundle.out"


def test_bundler_bad_input(exports, tmp_path, capsys):
    p = _bundler(tmp_path, exports, lambda s: s[:1000])
    _fails(capsys, p, "bundle.out", "line 1000", "the file ends early", "4 cameras and 1039 "
           "points need 3139 lines")
    # a view list naming camera 7 (there are 4): line of the point's view list
    def camera7(s):
        t = s[24].split()
        t[1] = "7"
        return s[:24] + [" ".join(t)] + s[25:]
    p = _bundler(tmp_path / "b", exports, camera7)
    _fails(capsys, p, "line 25", "view on camera 7, which does not exist (cameras 0..3)")
    # a view list whose count promises more views than follow
    p = _bundler(tmp_path / "c", exports, lambda s: s[:24] + [s[24] + " 1"] + s[25:])
    _fails(capsys, p, "line 25", "values follow")
    # a rotation that is not one: its first row doubled
    def scaled(s):
        s[3] = " ".join(str(2 * float(v)) for v in s[3].split())
        return s
    p = _bundler(tmp_path / "d", exports, scaled)
    _fails(capsys, p, "line 4", "camera 0: R is not a rotation")


def test_nvm_bad_input(exports, tmp_path, capsys):
    lines = exports[1].read_text().split("\n")
    cases = [(lines[:20], ["line 9", "1039 points announced, 11 lines follow (a truncated "
                                          "file)"]),
             (lines[:3] + [lines[3].replace(" 0.99", " 1.99", 1)] + lines[4:],
              ["line 4", "not a rotation (a unit quaternion expected)"])]
    t = lines[10].split()
    t[7] = "9"  # the first measurement on image 9 (there are 4)
    cases.append((lines[:10] + [" ".join(t)] + lines[11:],
                  ["line 11", "measurement on image 9, which does not exist (images 0..3)"]))
    for k, (text, expected) in enumerate(cases):
        p = tmp_path / f"bad{k}" / "m.nvm"
        p.parent.mkdir()
        p.write_text("\n".join(text))
        _fails(capsys, p, "m.nvm", *expected)


@pytest.mark.slow
def test_adjusted_as_colmap_and_converted_back(exports, tmp_path):
    """Acceptance (issue 38): the Bundler and NVM files of the COLMAP model adjust with
    --sigma-px 1 --calibrate none to COLMAP's redundancy and sigma0 (1e-6); `baarda convert
    RESULT --to bundler|nvm` re-read and re-adjusted gives the same sigma0 (1e-6)."""
    def adjust(path, out):
        assert main(["adjust", str(path), "--sigma-px", "1", "--calibrate", "none", "-o",
                     str(out), "-q"]) in (0, 5)
        s = json.loads((out / "summary.json").read_text())
        return s["redundancy"], s["sigma0"], s["n_rejected"]

    red, s0, rej = adjust(COLMAP, tmp_path / "colmap")
    assert red == 3566 and s0 == pytest.approx(0.4754116, rel=1e-6) and rej == 0
    for path in exports:
        r, s, _ = adjust(path, tmp_path / path.stem)
        assert r == red and s == pytest.approx(s0, rel=1e-6)
    for to, name in (("bundler", "bundle.out"), ("nvm", "model.nvm")):
        assert main(["convert", str(tmp_path / "colmap"), "--to", to, "-o",
                     str(tmp_path / to), "-q"]) == 0
        assert (tmp_path / to / "rejected.csv").read_text().startswith("photo,point,"
                                                                      "component,w,mdb")
        r, s, _ = adjust(tmp_path / to / name, tmp_path / f"{to}_again")
        assert r == red and s == pytest.approx(s0, rel=1e-6)


@pytest.mark.slow
def test_result_folder_goes_out_adjusted_without_its_rejections(tmp_path):
    """`baarda convert RESULT --to bundler|nvm`: the adjusted orientations (photos.csv, in
    gon here) and points (points.csv) go out, the rejected observations stay out and are
    listed with their w and MDB in rejected.csv."""


    demo = Path(__file__).resolve().parents[2] / "examples" / "demo"
    res = tmp_path / "res"
    assert main(["adjust", str(demo), "--snoop", "-o", str(res), "-q"]) == 0
    obs = pd.read_csv(res / "observations.csv", dtype={"photo": str, "point": str})
    rejected = obs[(obs["kind"] == "image") & obs["rejected"]]
    assert len(rejected) == 4
    photos = pd.read_csv(res / "photos.csv", dtype={"photo": str})
    points = pd.read_csv(res / "points.csv", dtype={"point": str})
    for to, name in (("bundler", "bundle.out"), ("nvm", "model.nvm")):
        out = tmp_path / to
        assert main(["convert", str(res), "--to", to, "-o", str(out), "-q"]) == 0
        listed = pd.read_csv(out / "rejected.csv", dtype={"photo": str, "point": str})
        assert listed[["photo", "point", "component"]].values.tolist() == \
            rejected[["photo", "point", "component"]].values.tolist()
        assert np.allclose(listed["w"], rejected["w"], rtol=1e-15)
        b = baarda.read(out / name)
        assert len(b.image) == 276 - 4
        ph = photos.set_index("photo").loc[b.photos.ids]
        eo = np.column_stack([ph[["X0", "Y0", "Z0"]],
                              np.deg2rad(ph[["omega", "phi", "kappa"]].to_numpy() * 0.9)])
        d = np.abs(b.photos.eo - eo)
        d[:, 3:] = np.abs((d[:, 3:] + np.pi) % (2 * np.pi) - np.pi)  # angles mod 2 pi
        assert d.max() <= 1e-9 * np.abs(eo).max()
        got = {tuple(np.round(x, 6)) for x in b.points.xyz}
        assert got == {tuple(np.round(x, 6)) for x in points[["X", "Y", "Z"]].to_numpy()}


def test_list_and_camera_models(exports, tmp_path, capsys):
    """list.txt must name every camera; without it the images are numbered (noted); a lens
    model the format cannot hold is an error naming the camera (exit 2), not a file that
    means something else."""
    p = _bundler(tmp_path, exports, lambda s: s)
    p.with_name("list.txt").write_text("00.jpg\n01.jpg\n")
    _fails(capsys, p, "list.txt", "2 image names, but the bundle file has 4 cameras")
    p.with_name("list.txt").unlink()
    b = baarda.read(p)
    assert b.photos.ids == ["0", "1", "2", "3"] and "the images are numbered" in b.notes[-2]
    block = baarda.read(COLMAP, camera_model="brown")
    coef = block.cameras.coefficients.copy()
    coef[0, 3] = 1e-6  # a decentring term
    block = replace(block, cameras=replace(block.cameras, coefficients=coef))
    with pytest.raises(ValueError, match="camera 1: model brown .* has no Bundler equivalent"):
        write_bundler(block, tmp_path / "w")
    with pytest.raises(ValueError, match="has no NVM equivalent"):
        write_nvm(block, tmp_path / "w")


@pytest.mark.slow
def test_bundler_radial_terms_are_colmaps(tmp_path):
    """Like with like for the lens: the Maupertuis model given a RADIAL camera (k1 -0.02,
    k2 0.005) adjusts (--calibrate none) as COLMAP and as its Bundler file to the same
    sigma0 (1e-6): Bundler's r(p) = 1 + k1 |p|^2 + k2 |p|^4 is COLMAP's RADIAL.  (NVM's one
    term is on the measured point, COLMAP's on the ideal one: r = -k is only a first-order
    match, so NVM is compared on the pinhole model above.)"""
    import pycolmap

    r = pycolmap.Reconstruction(str(COLMAP))
    cam = r.cameras[1]
    cam.model = pycolmap.CameraModelId.RADIAL
    cam.params = [1847.53, 959.5, 539.5, -0.02, 0.005]
    r.cameras[1] = cam
    (tmp_path / "radial").mkdir()
    r.write_text(str(tmp_path / "radial"))
    bundle = export_bundler(tmp_path / "radial", tmp_path / "bundler")
    assert baarda.read(bundle).cameras.coefficients[0, :2].tolist() == [-0.02, 0.005]
    sigma0 = []
    for path in (tmp_path / "radial", bundle):
        out = tmp_path / f"out{len(sigma0)}"
        assert main(["adjust", str(path), "--sigma-px", "1", "--calibrate", "none", "-o",
                     str(out), "-q"]) in (0, 5)
        s = json.loads((out / "summary.json").read_text())
        sigma0.append((s["redundancy"], s["sigma0"]))
    assert sigma0[0][0] == sigma0[1][0] == 3566
    assert sigma0[1][1] == pytest.approx(sigma0[0][1], rel=1e-6)
    assert sigma0[0][1] > 1.02 * 0.4754116  # 0.4909: the lens changes it, the terms are used


def test_counts_are_checked_before_anything_is_made(tmp_path):
    """A header announcing 10^15 cameras or points is a truncated file, not a MemoryError."""
    nvm = tmp_path / "big.nvm"
    nvm.write_text("NVM_V3\n\n1000000000000000\na.jpg 1 1 0 0 0 0 0 0 0 0\n")
    with pytest.raises(ProjectError, match="1000000000000000 cameras announced, 1 lines follow"):
        read_nvm(nvm)
    nvm.write_text("NVM_V3\n\n1\na.jpg 1 1 0 0 0 0 0 0 0 0\n1000000000000000\n")
    with pytest.raises(ProjectError, match="points announced, 0 lines follow"):
        read_nvm(nvm)
    out = tmp_path / "bundle.out"
    out.write_text("# Bundle file v0.3\n1000000000000000 1000000000000000\n")
    with pytest.raises(ProjectError, match="the file ends early"):
        baarda.read(out)


PIXELSTRUCT = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / \
    "bundler_pixelstruct" / "bundle.out"


def _bundler_sse(path: Path) -> tuple[float, int]:
    """Sum of squared reprojection errors [px^2] at the file's values by Bundler's formula
    (P = R X + t, p = -P.xy / P.z, x = f (1 + k1 |p|^2 + k2 |p|^4) p), written here from
    Bundler's documentation, and the number of views."""
    rows = path.read_text().split("\n")
    nc, npt = map(int, rows[1].split())
    cams = [np.array(" ".join(rows[2 + 5 * i:7 + 5 * i]).split(), float) for i in range(nc)]
    sse, n = 0.0, 0
    for j in range(npt):
        base = 2 + 5 * nc + 3 * j
        x = np.array(rows[base].split(), float)
        v = np.array(rows[base + 2].split()[1:], float).reshape(-1, 4)
        for c, _, u, w in v:
            f, k1, k2, *rt = cams[int(c)]
            r, t = np.array(rt[:9]).reshape(3, 3), np.array(rt[9:])
            pc = r @ x + t
            p = -pc[:2] / pc[2]
            q = p @ p
            sse += float(np.sum((f * (1 + k1 * q + k2 * q * q) * p - [u, w]) ** 2))
            n += 1
    return sse, n


@pytest.mark.skipif(not PIXELSTRUCT.is_file(), reason="PixelStruct's Bundler sample (GPL-2.0, "
                    f"not in the repository) not found at {PIXELSTRUCT}")
def test_real_bundler_output(tmp_path):
    """A file written by Bundler itself (pixelstruct's sample, 11 images of which 2 not
    reconstructed, no list.txt): read with its notes, and adjusted (f, k1, k2 held, 1 px)
    to the sum of squared reprojection errors of Bundler's own solution by Bundler's formula
    (430.8852 px^2) within 1e-7: Bundler's solution is already the minimum of the same sum,
    so baarda's projection of the file is Bundler's."""
    b = baarda.read(PIXELSTRUCT)
    assert (len(b.photos), len(b.points), len(b.image)) == (9, 631, 2033)
    assert any("2 camera(s) of all zeros" in n for n in b.notes)
    assert any("no list.txt" in n for n in b.notes)
    sse, n = _bundler_sse(PIXELSTRUCT)
    assert n == 2033
    out = tmp_path / "r"
    assert main(["adjust", str(PIXELSTRUCT), "--calibrate", "none", "-o", str(out),
                 "-q"]) in (0, 5)
    s = json.loads((out / "summary.json").read_text())
    assert s["redundancy"] == 2 * 2033 - (9 * 6 + 631 * 3 - 7)
    assert sse == pytest.approx(430.8852464, rel=1e-9)
    assert (1 - 1e-7) * sse <= s["vtpv"] <= sse


@pytest.mark.slow
def test_self_calibrated_result_goes_out_calibrated(exports, tmp_path):
    """A self-calibration (Bundler's f, k1, k2 estimated) converted to Bundler carries the
    adjusted f, k1, k2 (cameras.csv): re-adjusted with them held it has the same sum of
    squared residuals (1e-6), the redundancy 3 higher."""
    def adjust(path, out, *extra):
        assert main(["adjust", str(path), "-o", str(out), "-q", *extra]) in (0, 5)
        return json.loads((out / "summary.json").read_text())

    first = adjust(exports[0], tmp_path / "sc")
    assert main(["convert", str(tmp_path / "sc"), "--to", "bundler", "-o",
                 str(tmp_path / "b"), "-q"]) == 0
    cams = pd.read_csv(tmp_path / "sc" / "cameras.csv").set_index(
        "parameter")["value"]
    f, k1, k2 = (tmp_path / "b" / "bundle.out").read_text().split("\n")[2].split()
    assert float(f) == pytest.approx(cams["c"] / 0.001, rel=1e-15)
    assert (float(k1), float(k2)) == (cams["k1"], cams["k2"])
    again = adjust(tmp_path / "b" / "bundle.out", tmp_path / "again", "--calibrate", "none")
    assert again["redundancy"] == first["redundancy"] + 3
    assert again["vtpv"] == pytest.approx(first["vtpv"], rel=1e-6)


@pytest.mark.slow
def test_result_of_a_run_with_another_pixel_size(exports, tmp_path):
    """A run that read its input with --pixel-mm 0.004 goes out in the input's pixels (the
    run's observations.csv is in its mm): re-read with the default pixel and re-adjusted it
    gives the same sigma0 (1e-6)."""
    def adjust(path, out, *extra):
        assert main(["adjust", str(path), "--calibrate", "none", "-o", str(out), "-q",
                     *extra]) in (0, 5)
        return json.loads((out / "summary.json").read_text())

    first = adjust(exports[1], tmp_path / "r", "--pixel-mm", "0.004")
    assert main(["convert", str(tmp_path / "r"), "--to", "nvm", "-o", str(tmp_path / "n"),
                 "-q"]) == 0
    assert (tmp_path / "n" / "model.nvm").read_text().split("\n")[3].split()[1] == "1847.53"
    again = adjust(tmp_path / "n" / "model.nvm", tmp_path / "again")
    assert again["redundancy"] == first["redundancy"] == 3566
    assert again["sigma0"] == pytest.approx(first["sigma0"], rel=1e-6)


@pytest.mark.parametrize("writer", [write_bundler, write_nvm])
def test_another_pixel_size_goes_back_in_the_inputs_pixels(exports, tmp_path, writer):
    """A file read with pixel_mm=0.004 and written back has the same f in pixels (the
    writers take the reader's pixel frame, block/pixels.pixel_sizes)."""
    bundle, nvm = exports
    path = bundle if writer is write_bundler else nvm
    a = baarda.read(path, pixel_mm=0.004)
    assert a.cameras.pixel_frame is not None
    writer(a, tmp_path / "out")
    out = tmp_path / "out" / ("model.nvm" if writer is write_nvm else "")
    b = baarda.read(out, pixel_mm=0.004)
    assert np.allclose(b.cameras.focal_mm, a.cameras.focal_mm, rtol=1e-12, atol=0)
    f_in = baarda.read(path).cameras.focal_mm / 0.001
    f_out = baarda.read(out).cameras.focal_mm / 0.001
    assert np.allclose(f_out, f_in, rtol=1e-12, atol=0)
