"""PAT-B: read (io/patb.py), written (output/patb_files.py, `baarda convert --to patb`),
round trips of the demo and of a simulated block, bad input named by file, line and field.
No public PAT-B sample exists (tests/data/patb_demo/README.md): the sample is the demo
written by the layout of io/patb.py's docstring."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import baarda
from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.formats import detect
from baarda.output.patb_files import write_patb
from baarda.simulate.aerial import FlightPlan, simulate_block

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo"
SAMPLE = ROOT / "tests" / "data" / "patb_demo"


def same_block(a, b) -> None:
    """b is a read back: photos in order, orientations to 1e-9 relative, observations
    exactly (by photo and point id), the points' coordinates, sigmas and roles exactly."""
    assert b.photos.ids == a.photos.ids
    scale = np.abs(a.photos.eo).max()
    assert np.abs(b.photos.eo - a.photos.eo).max() <= 1e-9 * scale
    key = lambda blk: sorted(  # noqa: E731
        (blk.photos.ids[p], blk.points.ids[q], *blk.image.xy_mm[k], blk.image.sigma_mm[k])
        for k, (p, q) in enumerate(zip(blk.image.photo, blk.image.point, strict=True)))
    assert key(b) == key(a)
    used = sorted({a.points.ids[j] for j in a.image.point})
    ia, ib = a.point_index, b.point_index
    ja, jb = [ia[p] for p in used], [ib[p] for p in used]
    assert np.array_equal(b.points.role[jb], a.points.role[ja])
    given = a.points.role[ja] != "tie"
    assert np.array_equal(b.points.sigma[jb][given], a.points.sigma[ja][given], equal_nan=True)
    assert np.array_equal(b.points.xyz[jb], a.points.xyz[ja], equal_nan=True)
    cam = lambda blk: blk.cameras.focal_mm[blk.photos.camera]  # noqa: E731
    assert np.array_equal(cam(b), cam(a))


def test_sample_is_the_demo():
    """The sample (the demo written as PAT-B) is detected and read as the demo's block."""
    assert detect(SAMPLE) == "patb" and detect(SAMPLE / "demo.im") == "patb"
    a, b = baarda.read(DEMO), baarda.read(SAMPLE)
    assert b.summary() == a.summary()  # demo: 1 camera, 32 photos, 276 image points, ...
    same_block(a, b)
    assert b.settings.sigma_image_um == 5.0 and b.settings.datum == "control"


def test_round_trip_of_a_simulated_block(tmp_path):
    """A simulated block with height control, check points, per-observation sigmas and tie
    coordinates: written, read back, the same block."""
    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, pattern=3,
                                         height_chains=2, seed=3))
    sig = block.image.sigma_mm * (1 + (np.arange(len(block.image.photo)) % 3))
    role = block.points.role.copy()
    role[np.flatnonzero(role == "control")[:2]] = "check"
    xyz, sigma = block.points.xyz.copy(), block.points.sigma.copy()
    xyz[role == "tie"] += 0.25
    sigma[role == "check"] = np.nan
    sigma[np.flatnonzero(role == "check")[0]] = [0.02, 0.03, 0.04]  # a check point's own
    block = replace(block, image=replace(block.image, sigma_mm=sig),
                    points=replace(block.points, role=role, xyz=xyz, sigma=sigma))
    assert {"control", "check", "tie"} <= set(role)
    assert np.any(np.isnan(block.points.sigma[role == "control"]))  # height control
    notes = write_patb(block, tmp_path / "out", name="sim")
    assert any("no lens distortion" in n for n in notes)
    b = baarda.read(tmp_path / "out")
    same_block(block, b)


def test_lens_model_refused(tmp_path):
    block = baarda.read(DEMO)
    cams = replace(block.cameras, model=np.array(["brown"], dtype=object),
                   coefficients=np.array([[1e-5, 0, 0, 0, 0, 0, 0]]))
    with pytest.raises(ValueError, match="camera cam: model brown .* holds no lens"):
        write_patb(replace(block, cameras=cams), tmp_path)


def test_ids_the_format_cannot_hold(tmp_path):
    block = baarda.read(DEMO)
    for bad, match in (("-99", "photo id '-99' reads as the record end"),
                       ("-99.0", "photo id '-99.0' reads as the record end"),
                       ("a b", "photo id 'a b': the format's ids have no blanks")):
        photos = replace(block.photos, ids=[bad] + block.photos.ids[1:])
        with pytest.raises(ValueError, match=match):
            write_patb(replace(block, photos=photos), tmp_path)


def _copy(tmp_path: Path) -> Path:
    d = tmp_path / "p"
    shutil.copytree(SAMPLE, d)
    return d


def _fails(capsys, path: Path, *expected: str) -> None:
    assert main(["convert", str(path), "-o", str(path.parent / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    for e in expected:
        assert e in err, err


def _edit(d: Path, suffix: str, edit) -> None:
    f = d / f"demo{suffix}"
    f.write_text("\n".join(edit(f.read_text().split("\n"))))


def test_bad_input(tmp_path, capsys):
    """A truncated file, a -99 missing, a photo id unknown, a non-number field, a matrix
    that is not a rotation: exit 2 naming file, line and field."""
    d = _copy(tmp_path / "a")
    _edit(d, ".im", lambda s: s[:100] + [""])  # cut at a line end
    _fails(capsys, d / "demo.im", "demo.im, line 100", "not ended by -99")
    d = _copy(tmp_path / "b")
    _edit(d, ".im", lambda s: [x for k, x in enumerate(s) if not (x == "-99" and k < 15)])
    _fails(capsys, d / "demo.im", "demo.im, line", "found 2 field(s) (a -99 missing before "
           "a photo header?)")
    d = _copy(tmp_path / "c")
    _edit(d, ".ori", lambda s: ["99999 " + " ".join(s[0].split()[1:])] + s[1:])
    _fails(capsys, d / "demo.im", "demo.ori, line 1, column 'photo'", "photo 99999 is not "
           "one of the .im file's 32 photos")
    d = _copy(tmp_path / "d")
    _edit(d, ".im", lambda s: s[:2] + [s[2].replace(s[2].split()[2], "1.2.3")] + s[3:])
    _fails(capsys, d / "demo.im", "demo.im, line 3, column 'y'", "'1.2.3' is not a number")
    d = _copy(tmp_path / "e")
    _edit(d, ".con", lambda s: s[:-2])  # the closing -99 and the line end gone
    _fails(capsys, d / "demo.im", "demo.con", "the last line has no line end")
    d = _copy(tmp_path / "f")
    _edit(d, ".con", lambda s: s[:-3] + [""])  # a whole line and the -99 gone
    _fails(capsys, d / "demo.im", "demo.con, line 29", "ends without the closing -99")
    d = _copy(tmp_path / "g")
    _edit(d, ".ori", lambda s: s[:1] + [" ".join(str(2 * float(v)) for v in s[1].split())]
          + s[2:])
    _fails(capsys, d / "demo.im", "demo.ori, line 2, column 'R'", "photo 01001: not a "
           "rotation")
    d = _copy(tmp_path / "h")
    _edit(d, ".con", lambda s: [s[0].rsplit(" ", 4)[0] + " 7 0.05 0.05 0.1"] + s[1:])
    _fails(capsys, d / "demo.im", "demo.con, line 1, column 'code'", "code 7")


def test_convert_result_folder_leaves_rejected_out(tmp_path):
    """A result folder with snooping (4 rejections) goes out adjusted without them, listed
    in rejected.csv with w and MDB; every image observation of the file is one of the run's
    kept ones."""
    res = tmp_path / "res"
    assert main(["adjust", str(SAMPLE), "--snoop", "-o", str(res), "-q"]) == 0
    assert main(["convert", str(res), "--to", "patb", "-o", str(tmp_path / "out"),
                 "-q"]) == 0
    listed = (tmp_path / "out" / "rejected.csv").read_text().split("\n")
    assert listed[0] == "photo,point,component,w,mdb" and len([x for x in listed if x]) == 5
    b = baarda.read(tmp_path / "out")
    assert len(b.image) == 276 - 4


@pytest.mark.slow
def test_readjusted_gives_the_same_sigma0(tmp_path):
    """The demo and its PAT-B files adjust to the same sigma0 and redundancy (1e-6); the
    result folder converted to PAT-B and re-adjusted too."""
    def adjust(path, out):
        assert main(["adjust", str(path), "-o", str(out), "-q"]) in (0, 5)
        s = json.loads((out / "summary.json").read_text())
        return s["redundancy"], s["sigma0"]

    red, s0 = adjust(DEMO, tmp_path / "demo")
    assert red == 172 and s0 == pytest.approx(1.4629371, rel=1e-6)
    for path in (SAMPLE, SAMPLE / "demo.im"):
        r, s = adjust(path, tmp_path / f"p{len(path.name)}")
        assert r == red and s == pytest.approx(s0, rel=1e-6)
    assert main(["convert", str(tmp_path / "demo"), "--to", "patb", "-o",
                 str(tmp_path / "conv"), "-q"]) == 0
    r, s = adjust(tmp_path / "conv", tmp_path / "again")
    assert r == red and s == pytest.approx(s0, rel=1e-6)


def test_no_pro_and_unknown_points_are_noted(tmp_path):
    d = _copy(tmp_path)
    (d / "demo.pro").unlink()
    with open(d / "demo.at", "w") as f:
        f.write("nowhere 1 2 3\n-99\n")
    _edit(d, ".ori", lambda s: s[:-6] + s[-2:])  # the last photo's orientation gone
    b = baarda.read(d)
    assert any("no .pro: image sigma 5 µm" in n for n in b.notes)
    assert any("1 photo(s) without an orientation (.ori): approximated" in n for n in b.notes)
    assert np.isnan(b.photos.eo[-1]).all() and np.isfinite(b.photos.eo[:-1]).all()
    assert any("point nowhere (line 1) is measured on no photo" in n for n in b.notes)
    with pytest.raises(ProjectError, match="no .im file"):
        baarda.read(tmp_path, "patb")
