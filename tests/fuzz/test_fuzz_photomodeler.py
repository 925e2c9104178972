"""Fuzzing PhotoModeler exports (tests/data/dbat_sxb_aerial/photomodeler_export)."""

from fuzz.fuzzing import first_file, format_tests

test_read_photomodeler, test_adjust_photomodeler = format_tests(
    "photomodeler", "photomodeler_base", entry=first_file)
