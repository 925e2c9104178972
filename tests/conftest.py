import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from baarda.simulate.aerial import FlightPlan, simulate_block  # noqa: E402


@pytest.fixture(scope="session")
def small_block():
    """3 strips x 5 photos, 3x3 pattern, relief, 3 check points, noise, no blunders."""
    return simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=40.0,
                                     check_points=3, seed=11))
