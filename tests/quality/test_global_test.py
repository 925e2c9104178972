"""The headline global test at a conventional level (issue 18, part 1): noise-only blocks
are accepted as often as alpha_global says; the B-method's coupled test is printed beside
it; a-priori sigmas that are too pessimistic are named."""

import json
from dataclasses import replace

import numpy as np
from scipy.stats import chi2

from baarda.options import TestOptions
from baarda.pipeline import adjust, assess
from baarda.quality.assessment import global_test_lines, sigma0_interval
from baarda.simulate.aerial import FlightPlan, simulate_block


def _assessments(seeds, **kw):
    for seed in seeds:
        block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, pattern=5,
                                             relief_m=50.0, seed=seed, **kw))
        yield assess(adjust(block))


def test_noise_only_blocks_are_accepted_at_alpha_global():
    """40 blocks with correct sigmas: the headline test accepts >= 93 % (alpha 0.05); the
    B-method's test is the second line."""
    accepted = 0
    for a in _assessments(range(40)):
        q = a.quality
        h = q.headline_test
        assert h.alpha == 0.05 and np.isclose(h.critical, chi2.isf(0.05, q.redundancy)
                                              / q.redundancy)
        lines = global_test_lines(q)
        assert lines[0].startswith("global test at alpha 0.05") and \
            lines[1].startswith("global test by the B-method")
        accepted += bool(h.passed)
    assert accepted >= 0.93 * 40, accepted


def test_interval_and_pessimistic_sigmas():
    """Image noise 2.5 µm given as 5 µm: sigma0 about 0.5, its interval below one, said."""
    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, pattern=5,
                                         relief_m=50.0, seed=1, sigma_image_um=2.5))
    im = block.image
    block = replace(block, image=replace(im, sigma_mm=np.full(len(im), 0.005)))
    q = assess(adjust(block)).quality
    lo, hi = sigma0_interval(q.headline_test)
    r = q.redundancy
    s2 = q.headline_test.statistic
    assert np.isclose(lo, np.sqrt(s2 * r / chi2.isf(0.025, r)))
    assert np.isclose(hi, np.sqrt(s2 * r / chi2.ppf(0.025, r)))
    assert hi < 1 and "too pessimistic" in global_test_lines(q)[0]


def test_alpha_global_from_the_project_and_the_command_line(tmp_path):
    from baarda.cli import main

    proj = tmp_path / "p"
    assert main(["simulate", "-o", str(proj), "--pattern", "5"]) == 0
    toml = proj / "project.toml"
    toml.write_text(toml.read_text().replace("[tests]", "[tests]\nalpha_global = 0.01"))
    assert main(["adjust", str(proj), "-o", str(tmp_path / "a"), "-q"]) == 0
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["global_test"]["alpha"] == 0.01 and s["global_test_b_method"]["alpha"] > 0.1
    assert main(["adjust", str(proj), "-o", str(tmp_path / "b"), "-q",
                 "--alpha-global", "0.1"]) == 0
    s = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert s["global_test"]["alpha"] == 0.1
    assert TestOptions.resolve(None, alpha_global=0.2).alpha_global == 0.2
