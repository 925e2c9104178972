"""Fuzzing the native project (examples/demo: project.toml and four CSV files)."""

from fuzz.fuzzing import ADJUST_DEADLINE_MS, any_mutations, format_tests, read_test

from baarda.pipeline import read_models

test_read_project, test_adjust_project = format_tests("project", "project_base")

# read_models of a photo project forms stereo models by relative orientation
test_read_models_of_a_photo_project = read_test(
    "project read_models", "project_base", read_models, draw=any_mutations, computes=True,
    deadline_ms=ADJUST_DEADLINE_MS)
