"""A few generated cases through a real process (`python -m baarda adjust`): what a user
sees on the terminal, no traceback, exit code 0, 2 or 3."""

import subprocess
import sys
import tempfile
from pathlib import Path

from fuzz.fuzzing import (
    ADJUST_DEADLINE_MS,
    any_mutations,
    apply,
    check_output,
    fuzz_settings,
    snapshot,
    write_files,
)
from hypothesis import given
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[2]


@fuzz_settings("process", 6 * ADJUST_DEADLINE_MS)  # each starts an interpreter
@given(data=st.data())
def test_command_line_in_a_process(project_base, colmap_bin_base, photomodeler_base, work,
                                   data):
    base, entry = data.draw(st.sampled_from([
        (project_base, None), (colmap_bin_base, None),
        (photomodeler_base, photomodeler_base.names[0])]))
    muts = data.draw(any_mutations(base))
    with tempfile.TemporaryDirectory(dir=work) as d:
        root, out = Path(d) / "in", Path(d) / "out"
        root.mkdir()
        write_files(root, apply(base, muts))
        before = snapshot(root)
        p = subprocess.run([sys.executable, "-m", "baarda", "adjust",
                            str(root / entry if entry else root), "-o", str(out), "-q"],
                           capture_output=True, text=True, cwd=ROOT, timeout=120)
        assert p.returncode in (0, 2, 3), p.stderr
        assert "Traceback" not in p.stderr + p.stdout, p.stderr
        assert snapshot(root) == before
        check_output(out, p.returncode, p.stderr)
