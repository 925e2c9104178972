"""Fuzzing OpenSfM datasets (a part of OpenSfM's berlin example in tests/data: the
reconstruction, tracks, GCPs and config.yaml)."""

from fuzz.fuzzing import format_tests

test_read_opensfm, test_adjust_opensfm = format_tests("opensfm", "opensfm_base")
