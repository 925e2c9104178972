"""The accuracy statement by the ASPRS Positional Accuracy Standards, Edition 2 (2023)
(output/accuracy.py), checked against figures computed here point by point."""

import numpy as np
import pandas as pd
import pytest

from baarda.output.accuracy import (
    CONTROL,
    FREE_NONE,
    FREE_SIMILARITY,
    STANDARD,
    Survey,
    accuracy_class_cm,
    statement,
    survey_accuracy,
)


def misses(d: np.ndarray) -> pd.DataFrame:
    d = np.asarray(d, float)
    return pd.DataFrame({"point": [f"c{i}" for i in range(len(d))], "dX": d[:, 0],
                         "dY": d[:, 1], "dZ": d[:, 2]})


def random_misses(n: int, seed: int = 0, shift=(0.0, 0.0, 0.0)) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    return misses(rng.normal(0, [0.05, 0.04, 0.1], (n, 3)) + np.asarray(shift))


def test_edition2_figures_point_by_point_with_the_survey_accuracy():
    m = random_misses(35, seed=1)
    sig = np.tile([0.02, 0.02, 0.03], (35, 1))
    sig[0] = [0.01, 0.03, 0.05]  # the survey's RMS is over the points
    acc = statement(m, CONTROL, survey_accuracy(sig))
    d = m[["dX", "dY", "dZ"]].to_numpy()
    h1 = np.sqrt(sum(d[i, 0] ** 2 + d[i, 1] ** 2 for i in range(35)) / 35)
    v1 = np.sqrt(sum(d[i, 2] ** 2 for i in range(35)) / 35)
    h2 = np.sqrt(sum(sig[i, 0] ** 2 + sig[i, 1] ** 2 for i in range(35)) / 35)
    v2 = np.sqrt(sum(sig[i, 2] ** 2 for i in range(35)) / 35)
    f = acc.figures
    assert f["rmse_h1_m"] == pytest.approx(h1, rel=1e-12)
    assert f["rmse_v1_m"] == pytest.approx(v1, rel=1e-12)
    assert f["rmse_h2_m"] == pytest.approx(h2, rel=1e-12)
    assert f["rmse_v2_m"] == pytest.approx(v2, rel=1e-12)
    assert f["rmse_h_m"] == pytest.approx(np.sqrt(h1 ** 2 + h2 ** 2), rel=1e-12)
    assert f["rmse_v_m"] == pytest.approx(np.sqrt(v1 ** 2 + v2 ** 2), rel=1e-12)
    assert f["rmse_3d_m"] == pytest.approx(np.sqrt(h1 ** 2 + h2 ** 2 + v1 ** 2 + v2 ** 2),
                                           rel=1e-12)
    # 35 >= 30 check points: the standard's 'tested to meet' sentences
    h_cm = f"{100 * f['rmse_h_m']:.1f}"
    assert acc.sentences[0] == (
        f"This data set was tested to meet {STANDARD} for a "
        f"{accuracy_class_cm(f['rmse_h_m']):g} (cm) RMSE_H Horizontal Positional Accuracy "
        f"Class. The tested horizontal positional accuracy was found to be RMSE_H = {h_cm} "
        "(cm).")
    assert "RMSE_V Vertical Accuracy Class. NVA accuracy was found to be RMSE_V" in \
        acc.sentences[1]
    assert "RMSE_3D Three-Dimensional Positional Accuracy Class" in acc.sentences[2]
    assert not any("reduced" in w or "survey accuracy" in w for w in acc.warnings)
    d = acc.to_dict()
    assert d["standard"] == STANDARD == ("ASPRS Positional Accuracy Standards for Digital "
                                         "Geospatial Data, Edition 2 (2023)")
    assert d["minimum_check_points"] == 30 and d["maximum_check_points_needed"] == 120
    assert d["legacy"]["standard"].startswith("NSSDA (FGDC-STD-007.3-1998)")
    # the legacy figures come from the fit alone: 1.7308 RMSE_r, 1.96 RMSE_Z
    assert d["legacy"]["horizontal_95_m"] == pytest.approx(1.7308 * h1, rel=1e-12)
    assert d["legacy"]["vertical_95_m"] == pytest.approx(1.96 * v1, rel=1e-12)
    assert d["legacy"]["ce90_m"] == pytest.approx(1.5175 * h1, rel=1e-12)
    assert d["legacy"]["le90_m"] == pytest.approx(1.6449 * v1, rel=1e-12)
    rows = dict(acc.lines())
    assert rows["RMSE_H (horizontal)"] == (f"{f['rmse_h_m']:.3f} m: fit RMSE_H1 {h1:.4f} m, "
                                           f"survey RMSE_H2 {h2:.4f} m")
    assert rows["legacy (NSSDA 1998, ASPRS 2014)"].startswith(
        f"at 95 %: horizontal {1.7308 * h1:.3f} m, vertical {1.96 * v1:.3f} m; CE90")


def test_the_class_met_is_the_smallest_whole_centimetre():
    assert accuracy_class_cm(0.07997) == 8.0  # the demo's RMSE_H 0.0800 m
    assert accuracy_class_cm(0.08) == 8.0
    assert accuracy_class_cm(0.0801) == 9.0
    assert accuracy_class_cm(0.12069) == 13.0
    assert accuracy_class_cm(0.0042) == 0.5  # below 1 cm: tenths
    assert accuracy_class_cm(0.004) == 0.4


def test_below_30_check_points_the_reduced_checkpoint_statement():
    acc = statement(random_misses(29), CONTROL, None)
    assert all(s.startswith(f"This data set was tested as required by {STANDARD}. Although "
                            "the Standards call for a minimum of thirty (30) checkpoints, "
                            "this test was performed using ONLY 29 checkpoints. This data set "
                            "was produced to meet a ") for s in acc.sentences)
    assert all(s.endswith("using the reduced number of checkpoints.") for s in acc.sentences)
    assert dict(acc.lines())["check points"] == ("29: Edition 2 asks for at least 30 (at most "
                                                 "120 on large projects)")
    # the report's paragraph: the opening once, then the three classes
    text = acc.statement_text()
    assert text.count("Although the Standards call for") == 1
    assert text.count("This data set was produced to meet a") == 3
    acc = statement(random_misses(121), CONTROL, None)
    assert "more than the 120 needed on the largest projects" in dict(acc.lines())[
        "check points"]
    assert acc.statement_text() == " ".join(acc.sentences)


def test_without_survey_sigmas_the_figure_is_the_fit_and_says_so():
    m = random_misses(5)
    acc = statement(m, CONTROL, survey_accuracy(np.full((5, 3), np.nan)))
    assert acc.figures["rmse_h_m"] == acc.figures["rmse_h1_m"]
    assert acc.figures["rmse_v_m"] == acc.figures["rmse_v1_m"]
    text = " ".join(acc.warnings)
    assert "No survey accuracy of the check points (sigma_X, sigma_Y, sigma_Z in " \
        "ground_points.csv): Edition 2 includes it in the product's accuracy; the horizontal " \
        "and vertical accuracy stated is the fit to the check points alone." in text
    # one check point without sigma_Z: the vertical survey accuracy is not stated
    sig = np.tile([0.02, 0.02, 0.03], (5, 1))
    sig[2, 2] = np.nan
    s = survey_accuracy(sig)
    assert s.rmse_h2 == pytest.approx(np.hypot(0.02, 0.02)) and s.rmse_v2 is None
    acc = statement(m, CONTROL, s)
    assert acc.figures["rmse_v_m"] == acc.figures["rmse_v1_m"]
    assert acc.figures["rmse_h_m"] > acc.figures["rmse_h1_m"]
    assert "ground_points.csv; 1 of the 5 check points lack sigma_Z): Edition 2 includes it " \
        "in the product's accuracy; the vertical accuracy stated is the fit" in \
        " ".join(acc.warnings)
    assert Survey.from_dict(s.to_dict()) == s


def test_no_figure_from_fewer_than_three_check_points():
    for n in (1, 2):
        acc = statement(random_misses(n), CONTROL, None)
        assert not acc.stated and acc.figures == {} and acc.sentences == []
        assert acc.lines() == [("standard", STANDARD)]
        assert f"Only {n} check point(s): fewer than 3, so no accuracy figure is stated" in \
            " ".join(acc.warnings)
        d = acc.to_dict()
        assert d["figures"] == {} and d["statements"] == [] and d["legacy"] is None
    acc = statement(random_misses(0), CONTROL, None)
    assert "No check points were measured" in acc.warnings[0]


def test_free_network_says_whether_the_similarity_was_applied():
    one = statement(random_misses(1), FREE_NONE, None)
    assert not one.stated
    assert ("The datum is free (no control) and only 1 check point(s) were compared: the "
            "7-parameter similarity transformation onto the check points needs at least 3 "
            "(not collinear), so none was applied") in one.warnings[0]
    four = statement(random_misses(4), FREE_NONE, None)  # collinear: no similarity either
    assert not four.stated
    fit = statement(random_misses(5, shift=(0.2, 0, 0)), FREE_SIMILARITY, None,
                    np.eye(3) * 1e-6)
    assert fit.stated and "after a 7-parameter similarity transformation" in fit.warnings[0]
    assert not any("significant" in w for w in fit.warnings)  # the mean is not tested there


def test_mean_error_against_a_quarter_of_the_rmse_and_the_adjustments_covariance():
    m = random_misses(40, seed=2, shift=(0.03, 0.0, 0.0))
    d = m[["dX", "dY", "dZ"]].to_numpy()
    mean, rmse = d.mean(axis=0), np.sqrt((d ** 2).mean(axis=0))
    assert abs(mean[0]) > 0.25 * rmse[0] and abs(mean[1]) < 0.25 * rmse[1]
    # a mean as large as the datum's own uncertainty: flagged by the 25 % rule, not significant
    wide = statement(m, CONTROL, None, np.diag([0.03, 0.03, 0.05]) ** 2)
    text = " ".join(wide.warnings)
    assert ("Mean error larger than 25 % of the RMSE of its axis (Edition 2 asks for its cause "
            f"to be investigated): X {mean[0]:+.3f} m > {0.25 * rmse[0]:.3f} m.") in text
    assert "none significant at 5 %" in text and " Y " not in text.split(".")[0]
    z = wide.table["mean / sd"].to_numpy()
    np.testing.assert_allclose(z, mean / np.array([0.03, 0.03, 0.05]), rtol=1e-12)
    # a precise datum: the same mean is a systematic shift
    tight = statement(m, CONTROL, None, np.diag([0.003, 0.003, 0.005]) ** 2)
    sd = np.array([0.003, 0.003, 0.005])
    assert ", ".join(f"{a} {abs(mean[k] / sd[k]):.1f} sigma" for k, a in enumerate("XYZ")) \
        + "; X, Z significant at 5 %: a systematic shift" in " ".join(tight.warnings)
    assert abs(mean[1] / sd[1]) < 1.96 < abs(mean[2] / sd[2])
    # the survey's independent errors add sigma^2 / n to the mean's variance
    s = survey_accuracy(np.tile([0.02, 0.04, 0.06], (40, 1)))
    with_survey = statement(m, CONTROL, s, np.diag([0.03, 0.03, 0.05]) ** 2)
    np.testing.assert_allclose(with_survey.table["sd of mean m"],
                               np.sqrt(np.array([0.03, 0.03, 0.05]) ** 2
                                       + np.array([0.02, 0.04, 0.06]) ** 2 / 40), rtol=1e-12)
    # without the adjustment's covariance the mean is not tested for significance
    bare = statement(m, CONTROL, None)
    assert np.isnan(bare.table["sd of mean m"]).all()
    assert "significant" not in " ".join(bare.warnings)
