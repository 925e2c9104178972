"""The quality check of a run from its files (output/verdict.py): each row's colour and
numbers, on summaries made to trigger them."""

import math

import numpy as np
import pandas as pd

from baarda.output.verdict import FAIL, PASS, WARN, check_point_misses, failures, verdict


def summary(**kw) -> dict:
    s = {"converged": True, "iterations": 4, "snooping_converged": True,
         "snooping_incomplete": None, "rejection_log": [], "sigma0": 1.02,
         "global_test": {"statistic": 1.04, "critical": 1.19, "alpha": 0.05, "p_value": 0.3,
                         "passed": True, "sigma0_interval": [0.93, 1.15]},
         "alpha0": 0.001, "n_observations": 2000, "n_rejected": 0, "n_uncontrolled": 0,
         "n_check_points": 0, "observation_groups": {"image": {"x": "image"}}}
    s.update(kw)
    return s


def row(v, key):
    return next(r for r in v.rows if r.key == key)


def test_a_clean_run_passes_but_for_the_missing_check_points():
    v = verdict(summary())
    assert [r.status for r in v.rows] == [PASS, PASS, PASS, PASS, WARN, PASS, PASS]
    assert v.status == WARN and v.headline == "REVIEW: Check points"
    assert row(v, "rejections").text.endswith("= 2 false alarms expected")  # 0.001 x 2000


def test_not_converged_and_incomplete_snooping_fail_in_the_banners_words():
    s = summary(converged=False, notes=["not converged after 30 iterations"],
                snooping_incomplete="snooping incomplete: 3 component(s) still significant")
    v = verdict(s)
    assert v.status == FAIL
    assert row(v, "convergence").text == failures(s)[0]
    assert failures(s)[0].startswith("NOT CONVERGED") and "30 iterations" in failures(s)[0]
    assert row(v, "snooping").text == "SNOOPING INCOMPLETE: 3 component(s) still significant"


def test_global_test_rejected_and_sigma0_off():
    s = summary(sigma0=2.6, global_test={"statistic": 6.75, "critical": 1.05, "alpha": 0.05,
                                         "p_value": 0.0, "passed": False,
                                         "sigma0_interval": [2.52, 2.68]})
    v = verdict(s, pixel_um=4.0, image_sigma_um=2.0)
    assert row(v, "global").status == FAIL and "2.60 times as large" in row(v, "global").text
    r = row(v, "sigma0")
    assert r.status == WARN and "5.20 µm = 1.30 px against 2 µm = 0.50 px" in r.text
    # significant but immaterial (0.97): no warning
    ok = verdict(summary(sigma0=0.97, global_test={
        "statistic": 0.94, "critical": 1.04, "alpha": 0.05, "p_value": 0.99, "passed": True,
        "sigma0_interval": [0.947, 0.992]}))
    assert row(ok, "sigma0").status == PASS


def test_rejections_against_the_false_alarms_to_expect():
    log = [{"action": "reject", "observations": [f"image photo 1 point {i} x"]}
           for i in range(6)]
    v = verdict(summary(n_rejected=6, n_observations=1994, rejection_log=log))
    assert row(v, "rejections").status == WARN  # 6 > 2 x (0.001 x 2000)
    v = verdict(summary(n_rejected=4, n_observations=1996, rejection_log=log[:4]))
    assert row(v, "rejections").status == PASS  # 4 <= 2 x 2


def test_suspicious_gcps_are_the_rejected_less_the_restored():
    log = [{"action": "reject", "observations": ["control point 7 Y"]},
           {"action": "reject", "observations": ["control point 9 Z"]},
           {"action": "restore", "observations": ["control point 9 Z"]}]
    v = verdict(summary(rejection_log=log, observation_groups={"control": {"Y": "control Y"}}))
    r = row(v, "control")
    assert r.status == WARN and r.text == "1 component(s) rejected: point 7 Y"


def test_a_check_point_that_misses_fails():
    pts = pd.DataFrame({"point": ["a", "b", "t"], "role": ["check", "check", "tie"],
                        "dX": [0.02, 30.0, np.nan], "dY": [0.01, 4.0, np.nan],
                        "dZ": [0.03, -12.0, np.nan], "sigma_X": [0.1, 0.2, 0.1],
                        "sigma_Y": [0.1, 0.2, 0.1], "sigma_Z": [0.2, 0.1, 0.1]})
    m = check_point_misses(pts)
    assert list(m["point"]) == ["b", "a"]
    d = np.sqrt(30**2 + 4**2 + 12**2)
    assert m.loc[0, "d"] == d and m.loc[0, "ratio"] == d / np.sqrt(0.2**2 + 0.2**2 + 0.1**2)
    r = row(verdict(summary(n_check_points=2), pts), "check")
    assert r.status == FAIL and f"check point b misses by {d:.3g} m" in r.text
    r = row(verdict(summary(n_check_points=1), pts[pts["point"] != "b"]), "check")
    assert r.status == WARN and "fewer than 3" in r.text


def test_console_lines():
    lines = verdict(summary()).lines()
    assert lines[0] == "quality check REVIEW: Check points"
    assert lines[1].startswith("  PASS   Convergence: converged in 4 iterations")


def test_rejections_judged_by_the_probability_of_that_many_false_alarms():
    from scipy.stats import poisson

    # the 3,000-photo block of issue 42: 81 rejections against 0.001 x 55,600 = 55.6
    log = [{"action": "reject", "observations": [f"image photo 1 point {i} x"]}
           for i in range(81)]
    r = row(verdict(summary(n_rejected=81, n_observations=55_519, rejection_log=log)),
            "rejections")
    p = poisson.sf(80, 55.6)  # the Poisson approximation of the binomial
    assert r.status == WARN and "= 56 false alarms expected" in r.text
    got = float(r.text.split("P(at least 81 false alarms) = ")[1].split(":")[0])
    assert abs(got - p) < 0.1 * p and got < 0.001
    # 60 against 55.6 is chance (the old rule, 2 x alpha0 x n, passed both)
    r = row(verdict(summary(n_rejected=60, n_observations=55_540, rejection_log=log[:60])),
            "rejections")
    assert r.status == PASS and "as many as chance alone gives" in r.text
    assert "P(at least" not in row(verdict(summary()), "rejections").text


def test_global_test_accepted_with_sigma0_below_one_says_the_sigmas_are_pessimistic():
    gt = {"statistic": 0.1854, "critical": 1.018, "alpha": 0.05, "p_value": 1.0,
          "passed": True, "sigma0_interval": [0.426, 0.435]}  # MicMac
    r = row(verdict(summary(sigma0=0.431, global_test=gt)), "global")
    assert r.status == PASS
    assert "agree with the a-priori sigmas" not in r.text
    assert "significantly below 1 (95 % interval 0.426 .. 0.435): the a-priori sigmas are " \
           "pessimistic" in r.text
    assert "agree with the a-priori sigmas" in row(verdict(summary()), "global").text


def _points(roles: dict[str, str], sigma: float = 0.1) -> pd.DataFrame:
    return pd.DataFrame({"point": list(roles), "role": list(roles.values()),
                         "sigma_X": sigma, "sigma_Y": sigma, "sigma_Z": 2 * sigma})


def test_uncontrolled_tie_points_are_a_design_fact_with_its_remedy():
    sep = {"share_uncontrolled": 0.027, "two_ray_points": ["a", "b"],
           "uncontrolled_components": [{"point": "a", "component": "x", "frames": ["1", "2"]},
                                       {"point": "b", "component": "y", "frames": ["2", "3"]}]}
    pts = _points({"a": "tie", "b": "tie", "g": "control"})
    v = verdict(summary(n_uncontrolled=2, separability=sep, delta0=4.13), pts)
    r = row(v, "uncontrolled")
    assert r.status == "info" and v.status == WARN  # only the missing check points warn
    assert "measure them on a third photo" in r.text
    # the bound delta0 x sigma_P: 4.13 x sqrt(0.1^2 + 0.1^2 + 0.2^2) = 1.01 m
    assert f"by at most {4.13 * np.sqrt(0.06):.3g} m (point a)" in r.text
    # many of them: a weak design
    r = row(verdict(summary(n_uncontrolled=2, separability=dict(sep, share_uncontrolled=0.16),
                            delta0=4.13), pts), "uncontrolled")
    assert r.status == WARN and "more than 5 % of the block is not checked" in r.text
    # on a control point: the georeference may hold an undetected error
    sep2 = dict(sep, uncontrolled_components=[{"point": "g", "component": "Z",
                                               "frames": [""]}])
    r = row(verdict(summary(n_uncontrolled=1, separability=sep2, delta0=4.13), pts),
            "uncontrolled")
    assert r.status == WARN and "1 of them not on tie points' image coordinates (g Z)" in r.text


def test_a_camera_that_moved_beyond_its_standard_deviations_is_flagged():
    cal = [{"camera": "cam", "parameter": "c", "initial": 3.0, "value": 2.832, "sigma": 0.01,
            "estimated": True},
           {"camera": "cam", "parameter": "k1", "initial": 0.1, "value": 0.101, "sigma": 0.01,
            "estimated": True},
           {"camera": "cam", "parameter": "x0", "initial": 0.0, "value": 0.0, "sigma": None,
            "estimated": False}]
    r = row(verdict(summary(calibration=cal)), "camera")
    assert r.status == WARN and "c of camera cam by -0.168, -5.6 % (16.8 standard " \
        "deviations)" in r.text and "k1" not in r.text
    cal[0]["value"] = 3.02
    r = row(verdict(summary(calibration=cal)), "camera")
    assert r.status == PASS and "2 parameter(s) of 1 camera(s) estimated" in r.text
    assert all(r.key != "camera" for r in verdict(summary()).rows)


def test_a_rejected_gcp_that_chance_explains_passes_named():
    log = [{"action": "reject", "observations": ["control point 7 Y"]}]
    groups = {"control": {"X": "control X", "Y": "control Y", "Z": "control Z"}}
    pts = _points({str(i): "control" for i in range(22)})  # 66 components
    r = row(verdict(summary(rejection_log=log, observation_groups=groups), pts), "control")
    assert r.status == PASS and "point 7 Y" in r.text
    assert "P(at least 1 false alarms among 66 components) = 0.064" in r.text
    r = row(verdict(summary(rejection_log=log, observation_groups=groups), pts[:1]), "control")
    assert r.status == WARN  # 1 of 3 components: P = 0.003


def test_a_rejected_image_measurement_of_a_gcp_is_named():
    """A GCP marked in the wrong place on one image (--gcp-list, issue 38): its rejected
    image component is named by GCP and photo, a warning; a tie point's is not a GCP's."""
    log = [{"action": "reject", "observations": ["image photo IMG_0004 point GCP3 x"],
            "value": 13.14},
           {"action": "reject", "observations": ["image photo IMG_0001 point 17 y"],
            "value": -3.9}]
    pts = _points({"GCP3": "control", "17": "tie"}).assign(rays=[50, 3])
    r = row(verdict(summary(rejection_log=log), pts), "control")
    assert r.status == WARN and r.label == "Suspicious GCPs"
    assert r.text.startswith("1 image measurement(s) of GCPs rejected: GCP3 on photo "
                             "IMG_0004 (x); P(|w| >= 13.14 among the GCPs' 100 image "
                             "components) = 1.9e-37")
    assert all(x.key != "control" for x in verdict(summary(rejection_log=log[1:]), pts).rows)
    # a |w| of 3.3 among 100 components: chance (P = 1 - (1 - erfc(3.3 / sqrt 2))^100)
    log[0]["value"] = 3.3
    r = row(verdict(summary(rejection_log=log), pts), "control")
    p = 1 - (1 - math.erfc(3.3 / math.sqrt(2))) ** 100
    assert r.status == PASS and f"= {p:.2g}: chance alone gives as much" in r.text
