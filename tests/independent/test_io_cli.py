"""Model projects on disk: round trip, errors naming file/line/column, the commands."""

import json

import numpy as np
import pytest

from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.model_project import read_model_project
from baarda.output.project_files import write_model_project
from baarda.simulate.model_blocks import ModelPlan, simulate_models


@pytest.fixture
def project(tmp_path):
    blk, _ = simulate_models(ModelPlan(strips=2, models_per_strip=3, layout="fotef", seed=4))
    write_model_project(blk, tmp_path / "p")
    return blk, tmp_path / "p"


def test_round_trip(project):
    blk, path = project
    back = read_model_project(path)
    assert back.models == blk.models and set(back.points) == set(blk.points)
    assert all(type(p) is str for p in back.points)
    np.testing.assert_allclose(back.obs_xyz, blk.obs_xyz, rtol=1e-15)
    np.testing.assert_allclose(back.obs_sigma, blk.obs_sigma, rtol=1e-12)
    np.testing.assert_array_equal(np.array(back.points)[back.obs_point],
                                  np.array(blk.points)[blk.obs_point])
    j = [back.points.index(p) for p in blk.points]
    np.testing.assert_array_equal(back.pc[j], blk.pc)
    np.testing.assert_array_equal(np.isfinite(back.sigma[j]), np.isfinite(blk.sigma))
    np.testing.assert_allclose(back.xyz[j], blk.xyz, rtol=1e-15)
    assert list(back.strip) == list(blk.strip)


def test_correlations_round_trip(project, tmp_path):
    blk, _ = project
    m = len(blk.obs_model)
    corr = np.repeat(np.eye(3)[None], m, 0)
    corr[:, 0, 2] = corr[:, 2, 0] = 0.3
    blk.obs_cov = corr * blk.obs_sigma[:, :, None] * blk.obs_sigma[:, None, :]
    write_model_project(blk, tmp_path / "c")
    back = read_model_project(tmp_path / "c")
    np.testing.assert_allclose(back.obs_cov, blk.obs_cov, rtol=1e-8)


@pytest.mark.parametrize("edit,match", [
    (lambda t: t.replace("1.01,1,1011,point,", "1.01,1,1011,point,abc", 1), "column 'x_mm'"),
    (lambda t: t + t.splitlines()[1] + "\n", "given twice"),
    (lambda t: t.replace("1011,point,", "1011,pcx,", 1), "kind 'pcx'"),
    (lambda t: t.replace("1.01,1,", "1.01,2,", 1), "strip"),
    (lambda t: t.replace(",10,10,15", ",-10,10,15", 1), "positive"),
])
def test_bad_model_file_names_line_and_column(project, edit, match):
    _, path = project
    f = path / "models.csv"
    f.write_text(edit(f.read_text()))
    with pytest.raises(ProjectError, match=match) as e:
        read_model_project(path)
    assert "models.csv" in str(e.value) and "line" in str(e.value)


def test_bad_settings(project):
    _, path = project
    (path / "project.toml").write_text("[tests]\nalpha0 = 0.9\n")
    with pytest.raises(ProjectError, match="alpha0"):
        read_model_project(path)


@pytest.mark.parametrize("toml, match", [
    ("models = 1\n", "'models' must be a table"),  # was AttributeError
    ("sigma = [1, 2]\n", "'sigma' must be a table"),
    ("[sigma]\nmodel_xy_um = nan\n", "finite positive"),  # NaN was accepted
    ("[models]\npre_z_um = inf\n", "finite positive"),
    ("[tests]\nalpha0 = 1" + "0" * 400 + "\n", "not a number|int too large"),  # OverflowError
])
def test_settings_of_the_wrong_type_or_not_finite(project, toml, match):
    """Fuzz finds (issue 15)."""
    _, path = project
    (path / "project.toml").write_text(toml)
    with pytest.raises(ProjectError, match=match) as e:
        read_model_project(path)
    assert e.value.path.endswith("project.toml")


def test_command_writes_every_output(project, tmp_path, capsys):
    _, path = project
    out = tmp_path / "out"
    assert main(["models", str(path), "-o", str(out), "-q", "--deformations", "affinity"]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"summary.json", "models.csv", "points.csv", "observations.csv", "hypotheses.csv",
            "preadjustment.csv", "report.txt"} <= names
    s = json.loads((out / "summary.json").read_text())
    assert s["adjustments"]["3d"]["global_test"]["passed"]
    assert "decision" in s
    # the input folder is never an output
    assert main(["models", str(path), "-o", str(path), "-q"]) == 2
    # planimetry + height from the command line, and a bad option value
    out2 = tmp_path / "out2"
    assert main(["models", str(path), "-o", str(out2), "-q", "--2d", "--no-snoop",
                 "--deformations", "none"]) == 0
    obs = (out2 / "observations.csv").read_text()
    assert "\n2d," in obs and "\nheight," in obs
    assert main(["models", str(path), "-o", str(out2), "-q", "--deformations", "warp"]) == 2
    assert "warp" in capsys.readouterr().err


def test_simulate_command_and_bundle_project_input(tmp_path):
    assert main(["simulate-models", "-o", str(tmp_path / "s"), "--strips", "1", "--models",
                 "3", "--deformation", "torsion=10"]) == 0
    assert read_model_project(tmp_path / "s").n_models == 3
    assert main(["simulate", "-o", str(tmp_path / "b"), "--strips", "2", "--photos", "4",
                 "--control-spacing", "1", "--height-chains", "1"]) == 0
    assert main(["models", str(tmp_path / "b"), "-o", str(tmp_path / "bo"), "-q",
                 "--deformations", "none"]) == 0
    s = json.loads((tmp_path / "bo" / "summary.json").read_text())
    assert s["adjustments"]["3d"]["converged"]


@pytest.mark.parametrize("row, value, message", [
    (40, "1e160", "the normal equations overflow"),  # was ValueError of the Cholesky
    (1, "1e200", "the similarity of the models to the control has scale 0"),  # ZeroDivision
])
def test_model_coordinates_far_too_large(tmp_path, capsys, row, value, message):
    """Fuzz finds (issue 15): model coordinates far beyond any model reached numpy and the
    Cholesky factorisation as inf; now exit 2 with a GeometryError."""
    assert main(["simulate-models", "-o", str(tmp_path / "p")]) == 0
    f = tmp_path / "p" / "models.csv"
    lines = f.read_text().split("\n")
    parts = lines[row].split(",")
    parts[lines[0].split(",").index("x_mm")] = value
    lines[row] = ",".join(parts)
    f.write_text("\n".join(lines))
    capsys.readouterr()
    assert main(["models", str(tmp_path / "p"), "-o", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and not (tmp_path / "out").exists()
