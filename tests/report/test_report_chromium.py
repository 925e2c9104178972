"""Open the HTML report in headless Chromium: every plot must render; keep a screenshot.

Needs a chromium binary (Debian package 'chromium'; .ci/run installs it).  The screenshot
of the first page is written to tests/artifacts/report_first_page.png (gitignored).
"""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(n)), None)
ARTIFACTS = Path(__file__).parents[1] / "artifacts"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]

pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="no chromium binary found (install the Debian package "
    "'chromium'; .ci/run does): the HTML report's rendering is not checked here")


def chromium(args: list[str], profile: Path) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args],
                          capture_output=True, text=True, timeout=120)


def test_every_plot_renders_and_screenshot(report_case, tmp_path):
    url = report_case.html_path.resolve().as_uri()
    n_img = report_case.html.count("<img")
    assert n_img == 12  # with the histogram of MSB/MDB (issue 30)
    r = chromium(["--virtual-time-budget=10000", "--dump-dom", url], tmp_path / "p1")
    assert r.returncode == 0, r.stderr[-2000:]
    m = re.search(r'<p id="render-status" data-rendered="(\d+)" data-total="(\d+)">([^<]*)',
                  r.stdout)
    assert m, "the status script did not run: " + r.stdout[-500:]
    assert (int(m.group(1)), int(m.group(2))) == (n_img, n_img), m.group(3)
    assert "FAILED" not in m.group(3)
    ARTIFACTS.mkdir(exist_ok=True)
    shot = ARTIFACTS / "report_first_page.png"
    shot.unlink(missing_ok=True)
    r = chromium(["--window-size=1280,1600", "--hide-scrollbars", f"--screenshot={shot}",
                  url], tmp_path / "p2")
    assert r.returncode == 0, r.stderr[-2000:]
    data = shot.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    print(f"screenshot of the report's first page: {shot}")


def test_a_broken_plot_is_reported(report_case, tmp_path):
    """The check can fail: a plot whose PNG does not decode is counted and named."""
    html = report_case.html.replace('src="data:image/png;base64,iVBOR',
                                    'src="data:image/png;base64,AAAA', 1)
    page = tmp_path / "broken.html"
    page.write_text(html, encoding="utf-8")
    r = chromium(["--virtual-time-budget=10000", "--dump-dom", page.as_uri()], tmp_path / "p")
    m = re.search(r'data-rendered="(\d+)" data-total="(\d+)">([^<]*)', r.stdout)
    assert m and (int(m.group(1)), int(m.group(2))) == (11, 12)
    assert "PLOTS FAILED: Camera centres" in m.group(3)
