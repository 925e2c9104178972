"""Small simulated model blocks shared by the tests (module-scoped, deterministic)."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))  # model_dense.py

from baarda.independent.model_problem import adjust_models  # noqa: E402
from baarda.simulate.model_blocks import ModelPlan, simulate_models  # noqa: E402


@pytest.fixture(scope="session")
def small3d():
    blk, truth = simulate_models(ModelPlan(strips=2, models_per_strip=3, tilt_rad=0.01, seed=1))
    return blk, truth, adjust_models(blk, "3d")


@pytest.fixture(scope="session")
def small2d():
    blk, truth = simulate_models(ModelPlan(strips=2, models_per_strip=3, seed=2))
    return blk, truth, adjust_models(blk, "2d")
