import pytest

from baarda.planning.gruen_study import run_study


@pytest.fixture(scope="session")
def study():
    """Gruen's whole study: 4 blocks x 3 control distributions x single/twin (a few s)."""
    return run_study()
