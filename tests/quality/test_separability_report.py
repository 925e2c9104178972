"""The summary's separability lines (quality/separability_report.py)."""

import re

import baarda
from baarda.simulate.aerial import FlightPlan, simulate_block


def test_the_uncontrolled_rest_is_counted_in_components():
    """Issue 41: 'and N more' counted the (point, component) groups not named, while the
    total counts components: the rest is now total - the components named."""
    block, _ = simulate_block(FlightPlan(strips=1, photos_per_strip=4, pattern=7, seed=2))
    qc = baarda.assess(baarda.adjust(block))
    line = next(s for s in qc.summary().splitlines() if s.startswith("uncontrolled:"))
    total = int(re.match(r"uncontrolled: (\d+) active components", line).group(1))
    groups = re.findall(r"point \S+: [xy] on photos? ([\d, ]+?)(?:;|$)", line)
    named = sum(len(g.split(", ")) for g in groups)
    more = int(re.search(r"and (\d+) more component\(s\)$", line).group(1))
    assert len(groups) == 10 and named + more == total == 98
