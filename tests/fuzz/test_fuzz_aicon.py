"""Fuzzing AICON 3D Studio projects (.ior .eor .obc .phc .scale of a small simulated block
written by baarda.output.format_files.write_aicon), read from the folder or a file."""

from fuzz.fuzzing import format_tests
from hypothesis import strategies as st

ENTRIES = st.sampled_from(["fuzz.phc", None, "fuzz.eor", "fuzz.scale"])

test_read_aicon, test_adjust_aicon = format_tests("aicon", "aicon_base", entry=ENTRIES)
