"""The demo block under review, served in a background thread."""

import sys
from pathlib import Path

import pytest

from baarda.pipeline import read_configured
from baarda.review.session import ReviewSession

sys.path.insert(0, str(Path(__file__).parent))  # review_serving.py (importlib mode)

DEMO = Path(__file__).resolve().parents[2] / "examples" / "demo"


@pytest.fixture(scope="module")
def demo_read():
    return read_configured(DEMO)


@pytest.fixture
def demo_session(demo_read):
    session = ReviewSession(*demo_read)
    yield session
    session.close()
