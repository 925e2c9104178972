"""Control files (`--control FILE`, `baarda.read(control=FILE)`): DBAT's text format as
DBAT's loadcpt reads it and native ground_points.csv; the input's control replaced, ids
matched, unmatched ones named; the approximations of another frame dropped."""

from pathlib import Path

import numpy as np
import pytest

from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.control_file import read_control_file
from baarda.pipeline import read

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo"


@pytest.mark.parametrize("text, sigma", [
    ("# Id,X,Y,Z\n1001,CP1,0,1,0\n", [0, 0, 0]),  # the header lies: a name column (camcal)
    ("# Id,X,Y,Z\n1001,0,1,0\n", [0, 0, 0]),
    ("1001, 0, 1, 0, 0.001\n", [0.001] * 3),
    ("1001, a, 0, 1, 0, 0.02, 0.04\n", [0.02, 0.02, 0.04]),
    ("# Id, Name, X, Y, Z, sigmaX, sigmaY, sigmaZ\n1001, 7, 0, 1, 0, 0.02, 0.03, 0.04\n",
     [0.02, 0.03, 0.04]),  # a numeric name: the header names the column
])
def test_dbat_text_formats(tmp_path, text, sigma):
    p = tmp_path / "c.txt"
    p.write_text(text)
    cf = read_control_file(p)
    assert cf.ids == ["1001"] and np.allclose(cf.xyz, [[0, 1, 0]])
    assert np.allclose(cf.sigma[0], sigma) and cf.role[0] == "control"


@pytest.mark.parametrize("text, line, column", [
    ("1001, a, 0, 1\n", 1, None),
    ("1001, a, 0, 1, 0, 1, 2, 3, 4\n", 1, None),
    ("1001, a, 0, 1, 0, -0.1\n", 1, "sigma"),
    ("1001, 0, 1, 0\n1002, 0, x, 0\n", 2, "Y"),
    ("1001, 0, 1, 0\n# c\n1001, 0, 1, 0\n", 3, "id"),
    ("# only a comment\n", None, None),
])
def test_bad_control_files_name_line_and_field(tmp_path, text, line, column):
    p = tmp_path / "c.txt"
    p.write_text(text)
    with pytest.raises(ProjectError) as e:
        read_control_file(p)
    assert (e.value.path, e.value.line, e.value.column) == (str(p), line, column)


def test_native_ground_points_replace_the_control(tmp_path):
    """A ground_points.csv as the control of a native project: only its points are control
    (the project's other control points become tie points), roles kept."""
    lines = (DEMO / "ground_points.csv").read_text().splitlines()
    head, rows = lines[0], [r for r in lines[1:] if r.endswith(",control")][:5]
    rows[0] = rows[0].replace(",control", ",fixed")
    (tmp_path / "gp.csv").write_text("\n".join([head, *rows]) + "\n")
    b = read(DEMO, control=tmp_path / "gp.csv")
    pts = b.points
    assert int((pts.role == "control").sum()) == 5
    assert np.all(pts.sigma[pts.ids.index(rows[0].split(",")[0])] == 0)
    assert int((pts.role == "check").sum()) == 4  # the project's check points stay
    assert any("replaces the input's 26 control point(s)" in n for n in b.notes)


def test_dbat_control_for_a_project_ids_matched_and_unmatched_named(tmp_path):
    p = tmp_path / "c.txt"
    p.write_text("# Id, name, X, Y, Z, sigmaX, sigmaY, sigmaZ\n"
                 "001003, a, 920.0159700131895, -805.0434523623933, 24.885, 0.01, 0.01, 0.02\n"
                 "999999, b, 0, 0, 0, 0.01, 0.01, 0.02\n")
    b = read(DEMO, control=p)
    j = b.points.ids.index("001003")
    assert b.points.role[j] == "control" and np.allclose(b.points.sigma[j], [0.01, 0.01, 0.02])
    assert any("not points of the input" in n and "999999" in n for n in b.notes)
    assert np.isfinite(b.photos.eo).all()  # the same frame: approximations kept
    p.write_text("1, a, 0, 0, 0\n2, b, 1, 1, 1\n")
    with pytest.raises(ProjectError, match="none of its 2 point id") as e:
        read(DEMO, control=p)
    assert e.value.path == str(p)


def test_control_in_another_frame_moves_the_approximations(tmp_path):
    """The input's coordinates of the control points are 1e6 m away from the file's (a
    PhotoModeler export in its own frame): orientations and points are carried into the
    control's frame by a similarity, and the adjustment is the same as with the unshifted
    control."""
    lines = (DEMO / "ground_points.csv").read_text().splitlines()
    full = [r for r in lines[1:] if r.endswith(",control") and ",," not in r]
    (tmp_path / "gp.csv").write_text("\n".join([lines[0], *full]) + "\n")
    rows = [r.split(",") for r in full]
    text = "".join(f"{r[0]}, n, {float(r[1]) + 1e6}, {float(r[2]) - 2e5}, {r[3]}, "
                   f"{r[4]}, {r[5]}, {r[6]}\n" for r in rows)
    (tmp_path / "c.txt").write_text(text)
    b = read(DEMO, control=tmp_path / "c.txt")
    assert (b.points.role == "check").sum() == 0
    assert any("another frame" in n and "similarity from 10 points (scale 1," in n
               for n in b.notes)
    ref = read(DEMO)
    assert np.allclose(b.photos.eo[:, :3] - ref.photos.eo[:, :3], [1e6, -2e5, 0], atol=1e-6)
    assert np.allclose(b.photos.eo[:, 3:], ref.photos.eo[:, 3:], atol=1e-12)
    from baarda.pipeline import adjust

    shifted, plain = adjust(b), adjust(read(DEMO, control=tmp_path / "gp.csv"))
    assert shifted.redundancy == plain.redundancy  # check points are not observations
    assert abs(shifted.sigma0 / plain.sigma0 - 1) < 1e-6


def test_command_line_control(tmp_path):
    p = tmp_path / "c.txt"
    p.write_text("1, a, 0, 0, 0\n")
    assert main(["adjust", str(DEMO), "--control", str(p), "-o", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()
    assert main(["convert", str(DEMO), "--control", str(DEMO / "ground_points.csv"), "-o",
                 str(tmp_path / "c"), "-q"]) == 0
