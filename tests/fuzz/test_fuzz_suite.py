"""The suite's size (issue 15: at least 1,000 generated cases in CI)."""

import re
from pathlib import Path

from fuzz.fuzzing import CASES, SCALE, total_cases


def test_every_case_count_is_used_once_and_the_suite_has_at_least_1000():
    sources = "".join(p.read_text() for p in Path(__file__).parent.glob("test_fuzz_*.py"))
    used = re.findall(r'@fuzz_settings\("([^"]+)"', sources)
    assert sorted(used) == sorted(CASES)
    assert total_cases() * min(SCALE, 1.0) >= 1000
