"""Fuzzing AICON 3D Studio projects (.ior .eor .obc .phc .scale of a small simulated block
written by baarda.output.format_files.write_aicon), read from the folder or a file."""

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

ENTRIES = st.sampled_from(["fuzz.phc", None, "fuzz.eor", "fuzz.scale"])


@fuzz_settings("aicon read")
@given(data=st.data())
def test_read_aicon(aicon_base, work, data):
    read_case(aicon_base, data.draw(mutations(aicon_base)), work, read, data.draw(ENTRIES))


@fuzz_settings("aicon adjust", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_adjust_aicon(aicon_base, work, data):
    cli_case(aicon_base, data.draw(any_mutations(aicon_base)), work, ["adjust"],
             data.draw(ENTRIES))
