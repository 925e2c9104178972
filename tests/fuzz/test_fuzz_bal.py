"""Fuzzing BAL problem files, plain and bzip2-compressed (a small synthetic problem
written by baarda.output.format_files.write_bal)."""

from fuzz.fuzzing import first_file, format_tests

test_read_bal, test_adjust_bal = format_tests("bal", "bal_base", entry=first_file)
