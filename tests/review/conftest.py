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


@pytest.fixture(scope="session")
def big_read(tmp_path_factory):
    """A simulated block of 1,000 photos (20 strips of 50: 8,956 image points), read."""
    from baarda.cli import main

    out = tmp_path_factory.mktemp("big") / "block"
    assert main(["simulate", "-o", str(out), "--strips", "20", "--photos", "50", "-q"]) == 0
    block, config = read_configured(out)
    assert len(block.photos.ids) == 1000
    return block, config
