"""Fuzzing COLMAP sparse models: text and binary (a part of tests/data/colmap_maupertuis,
written back by baarda; and the whole text model)."""

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


@fuzz_settings("colmap text read")
@given(data=st.data())
def test_read_colmap_text(colmap_text_base, work, data):
    read_case(colmap_text_base, data.draw(mutations(colmap_text_base)), work, read)


@fuzz_settings("colmap whole model read")
@given(data=st.data())
def test_read_colmap_text_whole_model(colmap_full_base, work, data):
    read_case(colmap_full_base, data.draw(mutations(colmap_full_base)), work, read)


@fuzz_settings("colmap binary read")
@given(data=st.data())
def test_read_colmap_binary(colmap_bin_base, work, data):
    read_case(colmap_bin_base, data.draw(mutations(colmap_bin_base)), work, read)


@fuzz_settings("colmap text adjust", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_adjust_colmap_text(colmap_text_base, work, data):
    cli_case(colmap_text_base, data.draw(any_mutations(colmap_text_base)), work, ["adjust"])


@fuzz_settings("colmap binary adjust", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_adjust_colmap_binary(colmap_bin_base, work, data):
    cli_case(colmap_bin_base, data.draw(mutations(colmap_bin_base)), work, ["adjust"])
