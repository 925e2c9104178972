"""The suite's size (issue 15: at least 1,000 generated cases in CI)."""

import importlib
from pathlib import Path

from fuzz.fuzzing import CASES, SCALE, total_cases


def test_every_case_count_is_used_once_and_the_suite_has_at_least_1000():
    modules = [importlib.import_module(f"fuzz.{p.stem}")
               for p in sorted(Path(__file__).parent.glob("test_fuzz_*.py"))]
    used = [test.fuzz_case for m in modules for name, test in vars(m).items()
            if name.startswith("test_") and hasattr(test, "fuzz_case")]
    assert sorted(used) == sorted(CASES)
    assert total_cases() * min(SCALE, 1.0) >= 1000
