"""Fuzzing the native project (examples/demo: project.toml and four CSV files)."""

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

from baarda.pipeline import read, read_models


@fuzz_settings("project read")
@given(data=st.data())
def test_read_project(project_base, work, data):
    read_case(project_base, data.draw(mutations(project_base)), work, read)


@fuzz_settings("project adjust", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_adjust_project(project_base, work, data):
    cli_case(project_base, data.draw(any_mutations(project_base)), work, ["adjust"])


@fuzz_settings("project read_models", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_read_models_of_a_photo_project(project_base, work, data):
    """read_models of a photo project forms stereo models by relative orientation."""
    read_case(project_base, data.draw(any_mutations(project_base)), work, read_models,
              computes=True)
