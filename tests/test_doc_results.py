"""Figures the docs quote from recorded study and benchmark outputs (benchmarks/results/):
each stands both in the page and in the recorded output it comes from, so that neither is
changed without the other.  (Figures of runs that a test can make are checked by running
them: tests/test_doc_figures.py.)"""

import json
import re
import statistics
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"

# (page, recorded output, figures quoted in the page as the output has them)
QUOTED = [
    ("docs/online.md", "online_study_20x30.txt",
     ["0.972 [0.955, 0.983]", "0.887 [0.859, 0.911]", "0.983 [0.970, 0.992]",
      "1.000 [0.961, 1.000]", "0.359 [0.261, 0.465]", "0.687 [0.648, 0.724]",
      "0.851 [0.816, 0.882]", "0.193 [0.162, 0.227]", "37.85", "11.55",
      "0.798 [0.764, 0.830]", "located by both 522", "on-line only 61",
      "snooping only 10", "neither 7"]),
    ("docs/online.md", "online_study_8x15.txt",
     ["153/200 = 0.765 [0.700, 0.822]", "170/200 = 0.850 [0.793, 0.896]",
      "191/200 = 0.955 [0.916, 0.979]", "197/200 = 0.985 [0.957, 0.997]",
      "190/200 = 0.950 [0.910, 0.976]", "192/200 = 0.960 [0.923, 0.983]", "10.40", "3.15",
      "4.95", "0/37 = 0.000 [0.000, 0.095]", "10/37 = 0.270 [0.138, 0.441]"]),
    ("docs/online.md", "online_false_alarms.txt",
     ["12.55", "4.10", "5.25", "15.95", "37.85"]),
    ("docs/online.md", "online_remeasure_study_20x30.txt",
     ["0.980 [0.965, 0.990]", "57.95"]),
    ("docs/online.md", "online_remeasure.txt", ["3.70", "0.60 of 30", "1.0009"]),
    ("docs/online.md", "watch_colmap_mapper.txt",
     ["0.89 s", "0.23 s", "1.1e-15", "94.76 s", "25.03 s"]),
]


def _flat(text: str) -> str:
    return re.sub(r"\s+", " ", text)


@pytest.mark.parametrize("page, recorded, figures", QUOTED,
                         ids=[f"{p}:{r}" for p, r, _ in QUOTED])
def test_quoted_figures_stand_in_page_and_output(page, recorded, figures):
    text = _flat((ROOT / page).read_text())
    out = _flat((RESULTS / recorded).read_text())
    for f in figures:
        assert f in out, f"{f!r} is not in benchmarks/results/{recorded}"
        assert f in text, f"{f!r} is not in {page}"


def test_the_online_speed_quoted_is_the_recorded_run():
    """docs/online.md's and benchmarks/README.md's medians of the quiet run, from its raw
    times (results/online_1000_quiet.json)."""
    d = json.loads((RESULTS / "online_1000_quiet.json").read_text())
    point = statistics.median(d["points"]["ms"])
    photo = statistics.median(d["photos"]["ms"])
    batch = statistics.median(d["points"]["batch_ms"])
    for page in ("docs/online.md", "benchmarks/README.md"):
        text = _flat((ROOT / page).read_text())
        assert f"{point:.1f} ms" in text and f"{photo:.1f} ms" in text
        assert f"{batch:,.0f}" in text
