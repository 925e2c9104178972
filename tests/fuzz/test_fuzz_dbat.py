"""Fuzzing DBAT scripts: the XML and the files it names (tests/data/dbat_camcal_closerange
for reading, the smaller tests/data/dbat_sxb_aerial for adjusting)."""

from fuzz.fuzzing import (
    ADJUST_DEADLINE_MS,
    any_mutations,
    cli_case,
    fuzz_settings,
    mutations,
    read_case,
)
from hypothesis import given
from hypothesis import strategies as st

from baarda.pipeline import read


@fuzz_settings("dbat read")
@given(data=st.data())
def test_read_dbat(dbat_base, work, data):
    read_case(dbat_base, data.draw(mutations(dbat_base)), work, read, "camcaldemo.xml")


@fuzz_settings("dbat adjust", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_adjust_dbat(dbat_sxb_base, work, data):
    cli_case(dbat_sxb_base, data.draw(any_mutations(dbat_sxb_base)), work, ["adjust"],
             "sxb.xml")
