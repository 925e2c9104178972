"""Native project format (io/project.py): round trip with lens models, malformed files."""

from pathlib import Path

import numpy as np
import pytest

from baarda.errors import ProjectError
from baarda.io.dbat import read_dbat
from baarda.io.project import read_project
from baarda.output.project_files import write_project
from baarda.pipeline import with_approximations

SXB = Path(__file__).resolve().parents[1] / "data" / "dbat_sxb_aerial" / "dbat_script" / "sxb.xml"


@pytest.fixture()
def project(tmp_path):
    b = with_approximations(read_dbat(SXB))  # EO by space resection
    b.cameras.model = np.array(["brown_backward"], dtype=object)
    b.cameras.coefficients = np.array([[1e-5, -2e-9, 0.0, 3e-6, -4e-6]])
    write_project(b, tmp_path / "p")
    return b, tmp_path / "p"


def test_round_trip_with_lens_model(project):
    b, folder = project
    r = read_project(folder)
    assert list(r.cameras.model) == ["brown_backward"]
    assert np.array_equal(r.cameras.coefficients[:, :5], b.cameras.coefficients)
    assert not r.cameras.coefficients[:, 5:].any()  # b1, b2 of the brown model
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
    ("ground_points.csv", ",control\n", ",fxed\n", 2, "role"),
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


def test_photos_without_approximations_are_resected(tmp_path):
    """Empty orientation fields: the pipeline finds approximations by space resection."""
    from baarda.pipeline import adjust

    b = read_dbat(SXB)
    assert np.isnan(b.photos.eo).all()
    write_project(b, tmp_path / "p")
    r = read_project(tmp_path / "p")
    assert np.isnan(r.photos.eo).all()
    res = adjust(r)
    assert f"{res.sigma0:.4f}" == "1.1786"  # DBAT's report (tests/io/test_dbat.py)
    lines = (tmp_path / "p" / "photos.csv").read_text().splitlines()
    lines[1] = lines[1].rsplit(",", 1)[0] + ",12.5"  # kappa alone
    (tmp_path / "p" / "photos.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(ProjectError, match="photos.csv, line 2, column 'X0': give all six"):
        read_project(tmp_path / "p")
