"""Fuzzing DBAT scripts: the XML and the files it names (tests/data/dbat_camcal_closerange
for reading, the smaller tests/data/dbat_sxb_aerial for adjusting)."""

from fuzz.fuzzing import format_tests

test_read_dbat, test_adjust_dbat = format_tests(
    "dbat", "dbat_base", entry="camcaldemo.xml", cli_base="dbat_sxb_base",
    cli_entry="sxb.xml")
