"""Fuzzing PhotoModeler exports (tests/data/dbat_sxb_aerial/photomodeler_export)."""

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


@fuzz_settings("photomodeler read")
@given(data=st.data())
def test_read_photomodeler(photomodeler_base, work, data):
    base = photomodeler_base
    read_case(base, data.draw(mutations(base)), work, read, base.names[0])


@fuzz_settings("photomodeler adjust", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_adjust_photomodeler(photomodeler_base, work, data):
    base = photomodeler_base
    cli_case(base, data.draw(any_mutations(base)), work, ["adjust"], base.names[0])
