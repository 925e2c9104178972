"""Fuzzing the model project (models.csv, ground_points.csv, project.toml; written by
`baarda simulate-models`)."""

from fuzz.fuzzing import format_tests

from baarda.pipeline import read_models

test_read_model_project, test_models_command = format_tests(
    "models", "model_base", read=read_models, command=("models",), cli_name="models command")
