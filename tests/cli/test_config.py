"""One resolved configuration (issue 37): the command line, the API's arguments and
project.toml merged once; every command honours project.toml; a setting given twice is
resolved by the stated rule and noted; an unknown key in project.toml is an error."""

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm

from baarda.cli import main

ROOT = Path(__file__).parents[2]
DEMO = ROOT / "examples" / "demo"


def _demo(tmp_path: Path, extra: str = "", tests: str | None = None) -> Path:
    """A copy of the demo with `extra` appended to project.toml (and its [tests] replaced)."""
    proj = tmp_path / "proj"
    shutil.copytree(DEMO, proj)
    toml = (proj / "project.toml").read_text(encoding="utf-8")
    if tests is not None:
        toml = toml.split("[tests]")[0] + "[tests]\n" + tests + "\n"
    (proj / "project.toml").write_text(toml + extra, encoding="utf-8")
    return proj


def _delta0(alpha0: float, beta0: float) -> float:
    """The non-centrality of the one-dimensional test (B-method), independently."""
    return float(norm.ppf(1 - alpha0 / 2) + norm.ppf(beta0))


def test_plan_project_takes_alpha0_from_project_toml(tmp_path):
    """Bug 1: `plan --project` passed no settings: alpha0 = 0.01 gave delta0 4.132, not 3.417."""
    assert _delta0(0.01, 0.8) == pytest.approx(3.417, abs=5e-4)
    proj = _demo(tmp_path, tests="alpha0 = 0.01\nbeta0 = 0.8")
    out = tmp_path / "plan"
    assert main(["plan", "--project", str(proj), "-o", str(out), "--no-plots", "-q"]) == 0
    obs = pd.read_csv(out / "plan_observations.csv")
    img = obs[(obs["kind"] == "image") & (obs["redundancy"] > 1e-3)]
    ratio = img["mdb"] * np.sqrt(img["redundancy"]) / img["sigma"]
    assert np.allclose(ratio, _delta0(0.01, 0.8), rtol=2e-5)
    # the command line still wins over project.toml
    out2 = tmp_path / "plan2"
    assert main(["plan", "--project", str(proj), "-o", str(out2), "--no-plots", "-q",
                 "--alpha0", "0.001"]) == 0
    obs = pd.read_csv(out2 / "plan_observations.csv")
    img = obs[(obs["kind"] == "image") & (obs["redundancy"] > 1e-3)]
    ratio = img["mdb"] * np.sqrt(img["redundancy"]) / img["sigma"]
    assert np.allclose(ratio, _delta0(0.001, 0.8), rtol=2e-5)


def _unknowns(out: Path) -> int:
    return json.loads((out / "summary.json").read_text(encoding="utf-8")
                      )["n_unknowns"]


CAL = '\n[calibration]\nfree = ["c", "x0", "y0"]\n'


def test_camera_model_keeps_project_calibration(tmp_path, capsys):
    """Bug 2: --camera-model discarded project.toml's [calibration] free (429 -> 426
    unknowns, no note); now the free parameters the new model has stay free, said."""
    proj = _demo(tmp_path, CAL)
    assert main(["adjust", str(proj), "-o", str(tmp_path / "a"), "-q"]) == 0
    assert _unknowns(tmp_path / "a") == 429
    capsys.readouterr()
    for model in ("none", "brown"):
        out = tmp_path / model
        assert main(["adjust", str(proj), "-o", str(out), "-q", "--camera-model", model]) == 0
        assert _unknowns(out) == 429, model
        err = capsys.readouterr().err
        assert "c, x0, y0 estimated (project.toml [calibration] free)" in err, err
    # --calibrate on the command line replaces project.toml's list, said
    out = tmp_path / "cal"
    assert main(["adjust", str(proj), "-o", str(out), "-q", "--calibrate", "none"]) == 0
    assert _unknowns(out) == 426
    assert "over what the input sets" in capsys.readouterr().err


def test_project_calibration_and_another_camera_model(tmp_path, capsys):
    """project.toml's free list is checked against the run's camera model: k1 is no
    parameter of the demo's cameras (error naming project.toml), it is one of --camera-model
    brown (estimated), and --camera-model none drops it, said (the stated rule)."""
    proj = _demo(tmp_path, '\n[calibration]\nfree = ["c", "k1"]\n')
    assert main(["adjust", str(proj), "-o", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "project.toml" in err and "'k1' is not a parameter of its model (c, x0, y0)" in err
    assert main(["adjust", str(proj), "-o", str(tmp_path / "o"), "-q",
                 "--camera-model", "brown"]) == 0
    assert _unknowns(tmp_path / "o") == 426 + 2
    assert "--camera-model brown: c, k1 estimated (project.toml [calibration] free)" in \
        capsys.readouterr().err
    assert main(["adjust", str(proj), "-o", str(tmp_path / "p"), "-q",
                 "--camera-model", "none"]) == 0
    assert _unknowns(tmp_path / "p") == 426 + 1
    assert "c estimated (project.toml [calibration] free); k1 dropped (not a parameter of " \
        "camera model none)" in capsys.readouterr().err


@pytest.mark.parametrize("extra, key, accepted", [
    ('\n[calibration]\ncalibrate = ["c"]\n', "calibration.calibrate", "free, group"),
    ('\nalpha0 = 0.01\n', "alpha0", "angle_unit"),
    ('\n[tests]\nalpha = 0.01\n', "tests.alpha", "alpha0, beta0, alpha_global"),
    ('\n[sigma]\nimage = 3.0\n', "sigma.image", "image_um"),
    ('\n[gnss]\nlever = [0, 0, 0]\n', "gnss.lever", "lever_arm"),
    ('\n[imu]\nbore = "fixed"\n', "imu.bore", "boresight"),
    ('\n[solver]\ndamping = "lm"\n', "solver", "calibration"),
])
def test_unknown_project_key_is_an_error(tmp_path, capsys, extra, key, accepted):
    """An unknown key of project.toml (e.g. `calibrate`, the command line's word, under
    [calibration]) was ignored without a word: now exit 2 naming key, file and the keys
    accepted."""
    if extra.startswith("\n[tests]") or extra.startswith("\n[sigma]"):
        proj = _demo(tmp_path)
        toml = (proj / "project.toml").read_text(encoding="utf-8")
        section = extra.split("]")[0] + "]"
        toml = toml.replace(section, extra.strip())
        (proj / "project.toml").write_text(toml, encoding="utf-8")
    elif extra.startswith("\nalpha0"):
        proj = _demo(tmp_path)
        toml = (proj / "project.toml").read_text(encoding="utf-8")
        (proj / "project.toml").write_text(extra.strip() + "\n" + toml, encoding="utf-8")
    else:
        proj = _demo(tmp_path, extra)
    rc = main(["adjust", str(proj), "-o", str(tmp_path / "o"), "-q"])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "project.toml" in err and f"'{key}'" in err and accepted in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_one_configuration_from_three_sources(tmp_path, capsys):
    """read_configured: project.toml over the defaults, the API's (the command line's)
    values over project.toml, noted; the Config is frozen and prepare takes it."""
    from dataclasses import FrozenInstanceError

    from baarda.bundle.bundle_problem import SOLVE_LM
    from baarda.options import Requested, TestOptions
    from baarda.pipeline import prepare, read_configured

    proj = _demo(tmp_path, CAL, tests="alpha0 = 0.01\nbeta0 = 0.8")
    block, config = read_configured(proj)
    assert config.tests == TestOptions(0.01, 0.8, 0.05)
    assert config.calibration.free == (("c", "x0", "y0"),)
    assert config.calibration.source == "project.toml [calibration] free"
    assert (config.datum, config.solver, config.crs, config.notes) == ("control", None, None, ())
    assert block.settings.calibration_free == (("c", "x0", "y0"),)
    with pytest.raises(FrozenInstanceError):
        config.datum = "free"
    block, config = read_configured(proj, requested=Requested(
        alpha0=0.001, datum="free", solver="lm", calibrate="none", calibration_group="strip"))
    assert config.tests.alpha0 == 0.001 and config.calibration.free == ((),)
    assert config.calibration.group == "strip" and config.datum == "free"
    assert "--alpha0 0.001 (given) over project.toml's tests.alpha0 = 0.01" in config.notes
    assert config.notes[-1].startswith("calibrate none (every camera")
    assert all(n in block.notes for n in config.notes)
    problem = prepare(block, config=config)
    assert type(problem).__name__ == "FreeBundleProblem"
    assert problem.solve_options == SOLVE_LM
    # the command line says it too
    assert main(["adjust", str(proj), "-o", str(tmp_path / "o"), "--alpha0", "0.001"]) == 0
    assert "note: --alpha0 0.001 (given) over project.toml's tests.alpha0 = 0.01" in \
        capsys.readouterr().err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text(encoding="utf-8"))
    assert summary["alpha0"] == 0.001


def test_unknown_key_of_a_model_project(tmp_path, capsys):
    """A model project's project.toml names its keys too (io/model_project.MODEL_KEYS)."""
    from baarda.errors import ProjectError
    from baarda.io.model_project import read_settings

    f = tmp_path / "project.toml"
    f.write_text("[models]\npre_xy_um = 250\npre_z = 500\n", encoding="utf-8")
    with pytest.raises(ProjectError, match="unknown key 'models.pre_z': \\[models\\] accepts "
                       "pre_xy_um, pre_z_um") as e:
        read_settings(f)
    assert e.value.path == str(f) and e.value.column == "models.pre_z"
    f.write_text("[tests]\nalpha0 = 0.01\n", encoding="utf-8")
    assert read_settings(f).alpha0 == 0.01
