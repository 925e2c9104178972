"""Fuzzing OpenSfM datasets (a part of OpenSfM's berlin example in tests/data: the
reconstruction, tracks, GCPs and config.yaml)."""

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


@fuzz_settings("opensfm read")
@given(data=st.data())
def test_read_opensfm(opensfm_base, work, data):
    read_case(opensfm_base, data.draw(mutations(opensfm_base)), work, read)


@fuzz_settings("opensfm adjust", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_adjust_opensfm(opensfm_base, work, data):
    cli_case(opensfm_base, data.draw(any_mutations(opensfm_base)), work, ["adjust"])
