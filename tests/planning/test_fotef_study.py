"""FOTEF's empirical study (Appendix II) reproduced on simulated regular blocks."""

import numpy as np
import pytest

from baarda.planning.fotef_study import FOTEF, FOTEF_TABLE, headline, study_block


@pytest.fixture(scope="module")
def block_one():
    return study_block(2, 4, "2d", control_spacing=2)


def test_terrestrial_and_model_error_of_a_one_model_control_point_coincide(block_one):
    df = block_one
    one = df[df["class"] == "1 + T"]
    t = one[one.type == "TERR"].sort_values(["point", "component"])
    m = one[one.type == "MOD"].sort_values(["point", "component"])
    for col in ("nabla_cm", "point_prop", "same_prop", "diff_prop"):
        np.testing.assert_allclose(t[col].to_numpy(), m[col].to_numpy(), rtol=1e-6)


def test_boundary_values_agree_with_fotef(block_one):
    """Largest boundary value per class within 10 % of FOTEF's (same sigmas, delta0)."""
    df = block_one
    for cls, ((lo, hi), _) in FOTEF_TABLE.items():
        sel = df["class"] == cls
        if cls == "2 + T":
            sel &= df["type"] == "TERR"
        ours = df.loc[sel, "nabla_cm"].max()
        assert 0.9 * lo <= ours <= 1.1 * hi, (cls, ours)


def test_largest_effects_side_by_side_with_fotef(block_one):
    h = headline(block_one)
    assert set(h) == set(FOTEF)
    assert 0.5 <= h["control (1+T, 2+T)"] <= 0.8  # FOTEF 0.70
    assert 0.2 <= h["tie points"] <= 0.45  # FOTEF 0.30
    assert 0.4 <= h["distances"] <= 0.65  # FOTEF 0.50
    # and the ordering FOTEF found: control points hurt detail points most
    assert h["control (1+T, 2+T)"] > h["tie points"]
