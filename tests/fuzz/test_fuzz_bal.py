"""Fuzzing BAL problem files, plain and bzip2-compressed (a small synthetic problem
written by baarda.output.format_files.write_bal)."""

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


@fuzz_settings("bal read")
@given(data=st.data())
def test_read_bal(bal_base, work, data):
    read_case(bal_base, data.draw(mutations(bal_base)), work, read, bal_base.names[0])


@fuzz_settings("bal adjust", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_adjust_bal(bal_base, work, data):
    cli_case(bal_base, data.draw(any_mutations(bal_base)), work, ["adjust"], bal_base.names[0])
