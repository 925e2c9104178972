"""Reading, validation messages and round trip of the native project format."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from baarda.errors import GeometryError, ProjectError
from baarda.io.project import read_project
from baarda.output.project_files import write_project
from baarda.pipeline import adjust

DEMO = Path(__file__).parents[2] / "examples" / "demo"

@pytest.fixture()
def project(tmp_path, small_block):
    block, _ = small_block
    write_project(block, tmp_path / "p")
    return tmp_path / "p"


def edit(path, old, new, count=1):
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, count))


def set_field(path, row: int, column: int, value: str) -> None:
    """Field `column` of data row `row` (1: the first after the header) of a CSV file."""
    lines = path.read_text().splitlines()
    parts = lines[row].split(",")
    parts[column] = value
    lines[row] = ",".join(parts)
    path.write_text("\n".join(lines) + "\n")


def line_of(path, needle):
    for i, line in enumerate(path.read_text().splitlines(), start=1):
        if needle in line:
            return i
    raise AssertionError(needle)


def test_round_trip(project, small_block):
    block, _ = small_block
    b2 = read_project(project)
    assert b2.photos.ids == block.photos.ids
    assert np.allclose(b2.photos.eo, block.photos.eo, atol=1e-12)
    assert np.allclose(b2.image.xy_mm, block.image.xy_mm, atol=0)
    order = [b2.point_index[p] for p in block.points.ids]
    assert np.array_equal(b2.points.role[order], block.points.role)
    assert np.allclose(np.nan_to_num(b2.points.sigma[order], nan=-1),
                       np.nan_to_num(block.points.sigma, nan=-1))


def test_unknown_photo_reference(project):
    f = project / "image_points.csv"
    lines = f.read_text().splitlines()
    lines[3] = "NOPHOTO" + lines[3][lines[3].index(","):]
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(ProjectError) as e:
        read_project(project)
    assert e.value.line == 4 and e.value.column == "photo"
    assert "unknown photo 'NOPHOTO'" in str(e.value) and "image_points.csv" in str(e.value)


def test_unknown_camera(project):
    edit(project / "photos.csv", ",cam,", ",lens2,")
    with pytest.raises(ProjectError, match=r"photos.csv, line 2, column 'camera': unknown "
                                           r"camera 'lens2'"):
        read_project(project)


def test_duplicate_id(project):
    f = project / "photos.csv"
    lines = f.read_text().splitlines()
    f.write_text("\n".join(lines + [lines[1]]) + "\n")
    with pytest.raises(ProjectError, match=rf"line {len(lines) + 1}, column 'photo': duplicate"):
        read_project(project)


def test_duplicate_measurement(project):
    f = project / "image_points.csv"
    lines = f.read_text().splitlines()
    f.write_text("\n".join(lines + [lines[5]]) + "\n")
    with pytest.raises(ProjectError, match="measured twice"):
        read_project(project)


def test_not_a_number(project):
    f = project / "ground_points.csv"
    lines = f.read_text().splitlines()
    parts = lines[2].split(",")
    parts[3] = "12,5".replace(",", ";")
    lines[2] = ",".join(parts)
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(ProjectError) as e:
        read_project(project)
    assert (e.value.line, e.value.column) == (3, "Z")
    assert "'12;5' is not a number" in str(e.value)


def test_missing_column_and_wrong_field_count(project):
    edit(project / "cameras.csv", "focal_mm", "focal")
    with pytest.raises(ProjectError, match="missing column 'focal_mm'"):
        read_project(project)
    edit(project / "cameras.csv", "focal", "focal_mm")
    edit(project / "cameras.csv", "cam,153.0,", "cam,153.0,0.0,")
    with pytest.raises(ProjectError, match="line 2: expected 4 fields, found 5"):
        read_project(project)


def test_bad_settings(project):
    edit(project / "project.toml", 'angle_unit = "gon"', 'angle_unit = "grad"')
    with pytest.raises(ProjectError, match="angle_unit 'grad'"):
        read_project(project)


@pytest.mark.parametrize("first, old, new, column", [
    ('sigma = "gon"', "[sigma]", "[x]", "sigma"),  # was AttributeError
    ("tests = 5", "[tests]", "[x]", "tests"),
    ("", "image_um = 5.0", "image_um = nan", "sigma.image_um"),  # NaN, inf were accepted
    ("", "control_m = [0.05, 0.05, 0.1]", "control_m = [0.05, inf, 0.1]",
     "sigma.control_m[1]"),
    ("", "control_m = [0.05, 0.05, 0.1]", "control_m = [0.05, 0.05]", "sigma.control_m"),
    ("crs = 5", "", "", "crs"),
    ("", "image_um = 5.0", "image_um = 1" + "0" * 400, None),  # was OverflowError
])
def test_settings_of_the_wrong_type_or_not_finite(tmp_path, first, old, new, column):
    """Fuzz finds (issue 15): a key that should hold a table holding a value, NaN or inf
    standard deviations, a CRS that is not a string."""
    shutil.copytree(DEMO, tmp_path / "demo")
    f = tmp_path / "demo" / "project.toml"
    f.write_text(first + "\n" + f.read_text().replace(old, new))
    with pytest.raises(ProjectError) as e:
        read_project(tmp_path / "demo")
    assert e.value.path.endswith("project.toml") and e.value.column == column


def test_carriage_returns_and_quotes(tmp_path):
    """Fuzz find (issue 15): a file with CR line ends and a quote was one line with CRs
    inside, which the csv module refused with its own error (_csv.Error)."""
    shutil.copytree(DEMO, tmp_path / "demo")
    ref = read_project(tmp_path / "demo")
    for name in ("cameras.csv", "photos.csv"):
        f = tmp_path / "demo" / name
        f.write_bytes(f.read_bytes().replace(b"\n", b"\r").replace(b"cam,", b'"cam",'))
    block = read_project(tmp_path / "demo")  # CR-only line ends, as the other readers take
    assert block.photos.ids == ref.photos.ids
    assert np.array_equal(block.photos.eo, ref.photos.eo)
    f = tmp_path / "demo" / "cameras.csv"
    f.write_bytes(b'camera,focal_mm,x0_mm,y0_mm\ncam,"153.0\r",0,0\n')
    with pytest.raises(ProjectError, match="expected 4 fields, found 2") as e:
        read_project(tmp_path / "demo")
    assert e.value.path == str(f) and e.value.line == 2
    f.write_bytes(b'camera,focal_mm,x0_mm,y0_mm\ncam,"' + b"1" * 200_000 + b'",0,0\n')
    with pytest.raises(ProjectError, match="not a CSV record: field larger") as e:
        read_project(tmp_path / "demo")  # the csv module's limit, was _csv.Error
    assert e.value.path == str(f) and e.value.line == 2


def test_header_that_is_not_utf8(tmp_path):
    """Fuzz find (issue 15): a byte that is not UTF-8 in the header line of a plain CSV
    file escaped the fast reader as a UnicodeDecodeError."""
    shutil.copytree(DEMO, tmp_path / "demo")
    f = tmp_path / "demo" / "cameras.csv"
    f.write_bytes(b"\xff" + f.read_bytes())
    with pytest.raises(ProjectError, match="not utf-8 text: byte 0xff") as e:
        read_project(tmp_path / "demo")
    assert e.value.path == str(f) and e.value.line == 1


def test_bad_role_and_sigma(project):
    edit(project / "ground_points.csv", ",control", ",contrl")
    with pytest.raises(ProjectError, match="role 'contrl' must be 'control', 'fixed' or 'check'"):
        read_project(project)
    edit(project / "ground_points.csv", ",contrl", ",control")
    set_field(project / "ground_points.csv", 1, 4, "-0.05")
    with pytest.raises(ProjectError, match="line 2, column 'sigma_X': standard deviation"):
        read_project(project)


def test_a_ground_sigma_beyond_1000_km_is_refused(project):
    """Fuzz find (FUZZ_STRICT): a control sigma of 1e200 m overflowed sigma^2 in the
    statistics (r NaN); a ground sigma is at most 1e6 m, in the file and in project.toml."""
    set_field(project / "ground_points.csv", 1, 6, "1e200")
    with pytest.raises(ProjectError, match="line 2, column 'sigma_Z': standard deviation "
                                           "1e[+]200 m: at most 1e[+]06 m"):
        read_project(project)
    set_field(project / "ground_points.csv", 1, 6, "1e6")
    assert read_project(project).points.sigma[0, 2] == 1e6  # the bound itself is taken
    toml = project / "project.toml"
    edit(toml, "control_m = [0.05, 0.05, 0.1]", "control_m = [0.05, 0.05, 2e6]")
    with pytest.raises(ProjectError, match=r"sigma.control_m\[2\] = 2000000.0: at most 1e[+]06"):
        read_project(project)


def test_one_ray_points_are_left_out_and_listed(project):
    f = project / "image_points.csv"
    f.write_text(f.read_text() + "01001,LONELY,1.0,2.0,5\n")
    block = read_project(project)
    res = adjust(block)
    assert any("LONELY" in n and "one photo only" in n for n in res.notes)
    assert block.point_index["LONELY"] not in set(res.problem.point_ids)


def test_datum_defect_reported_before_adjusting(project):
    f = project / "ground_points.csv"
    lines = f.read_text().splitlines()
    ctrl = [ln for ln in lines[1:] if ln.endswith("control")]
    keep = [lines[0]] + ctrl[:1] + [ln for ln in lines[1:] if ln.endswith("check")]
    f.write_text("\n".join(keep) + "\n")
    with pytest.raises(GeometryError, match="datum defect.*1 planimetric.*at least two"):
        adjust(read_project(project))


def test_inputs_are_not_modified(project, tmp_path):
    before = {p.name: p.read_bytes() for p in project.iterdir()}
    from baarda.cli import main
    assert main(["adjust", str(project), "-o", str(tmp_path / "out"), "-q"]) == 0
    assert {p.name: p.read_bytes() for p in project.iterdir()} == before
    assert main(["adjust", str(project), "-o", str(project), "-q"]) == 2


def test_missing_file(project, capsys):
    shutil.rmtree(project / "cameras.csv", ignore_errors=True)
    (project / "cameras.csv").unlink()
    from baarda.cli import main
    assert main(["adjust", str(project), "-o", str(project.parent / "o"), "-q"]) == 2
    assert "cameras.csv: file not found" in capsys.readouterr().err
