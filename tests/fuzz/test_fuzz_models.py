"""Fuzzing the model project (models.csv, ground_points.csv, project.toml; written by
`baarda simulate-models`)."""

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

from baarda.pipeline import read_models


@fuzz_settings("models read")
@given(data=st.data())
def test_read_model_project(model_base, work, data):
    read_case(model_base, data.draw(mutations(model_base)), work, read_models)


@fuzz_settings("models command", ADJUST_DEADLINE_MS)
@given(data=st.data())
def test_models_command(model_base, work, data):
    cli_case(model_base, data.draw(any_mutations(model_base)), work, ["models"])
