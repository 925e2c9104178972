"""Native project format (io/project.py): round trip with lens models, malformed files."""

from pathlib import Path

import numpy as np
import pytest

from baarda.errors import ProjectError
from baarda.io.dbat import read_dbat
from baarda.io.project import read_project
from baarda.output.project_files import write_project

SXB = Path(__file__).resolve().parents[1] / "data" / "dbat_sxb_aerial" / "dbat_script" / "sxb.xml"


@pytest.fixture()
def project(tmp_path):
    b = read_dbat(SXB)
    b.cameras.model = np.array(["brown_backward"], dtype=object)
    b.cameras.distortion = np.array([[1e-5, -2e-9, 0.0, 3e-6, -4e-6]])
    write_project(b, tmp_path / "p")
    return b, tmp_path / "p"


def test_round_trip_with_lens_model(project):
    b, folder = project
    r = read_project(folder)
    assert list(r.cameras.model) == ["brown_backward"]
    assert np.array_equal(r.cameras.distortion, b.cameras.distortion)
    assert np.array_equal(r.image.xy_mm, b.image.xy_mm)
    assert np.allclose(r.photos.eo, b.photos.eo, rtol=0, atol=1e-9)


def _edit(folder: Path, name: str, old: str, new: str, count: int = 1):
    p = folder / name
    text = p.read_text()
    assert old in text
    p.write_text(text.replace(old, new, count))


@pytest.mark.parametrize("name, old, new, line, column", [
    ("cameras.csv", "brown_backward", "fisheye", 2, "model"),
    ("cameras.csv", ",1e-05,", ",abc,", 2, "k1"),
    ("cameras.csv", "123.9392", "-1", 2, "focal_mm"),
    ("photos.csv", "8811,Aerial camera", "8811,Other camera", 2, "camera"),
    ("image_points.csv", "8811,317,", "8811,317,x", 2, "x_mm"),
    ("ground_points.csv", ",control\n", ",fixed\n", 2, "role"),
])
def test_malformed(project, name, old, new, line, column):
    _, folder = project
    _edit(folder, name, old, new)
    with pytest.raises(ProjectError) as e:
        read_project(folder)
    assert Path(e.value.path).name == name and e.value.line == line
    assert e.value.column == column


def test_missing_file(project):
    _, folder = project
    (folder / "photos.csv").unlink()
    with pytest.raises(ProjectError, match="file not found"):
        read_project(folder)
