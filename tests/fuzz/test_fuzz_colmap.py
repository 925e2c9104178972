"""Fuzzing COLMAP sparse models: text and binary (a part of tests/data/colmap_maupertuis,
written back by baarda; and the whole text model)."""

from fuzz.fuzzing import format_tests, mutations, read_test

from baarda.pipeline import read

test_read_colmap_text, test_adjust_colmap_text = format_tests("colmap text",
                                                              "colmap_text_base")
test_read_colmap_text_whole_model = read_test("colmap whole model read", "colmap_full_base",
                                              read)
test_read_colmap_binary, test_adjust_colmap_binary = format_tests(
    "colmap binary", "colmap_bin_base", cli_draw=mutations)
