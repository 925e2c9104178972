"""Issue 40: a plain `baarda adjust` imports only the heavy libraries the job needs (the
reports' matplotlib and jinja2, pyproj without a CRS, scipy.stats, dask's distributed are
left out: each costs a user start-up time on every command)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("pandas", "pyarrow", "matplotlib", "jinja2", "pyproj", "scipy.stats", "numba",
         "distributed")
CODE = """
import runpy, sys
sys.argv = ["baarda", "adjust", sys.argv[1], "-o", sys.argv[2], "-q"]
try:
    runpy.run_module("baarda", run_name="__main__")
except SystemExit as e:
    code = e.code
print(" ".join(m for m in {heavy!r} if m in sys.modules))
print(code)
"""


def test_a_plain_adjust_of_the_demo_imports_only_what_it_needs(tmp_path):
    out = subprocess.run([sys.executable, "-c", CODE.format(heavy=HEAVY),
                          str(ROOT / "examples" / "demo"), str(tmp_path / "o")],
                         capture_output=True, text=True, check=True).stdout.split("\n")
    # the table reader (pyarrow, pandas), the kernels (numba); no report, statistics
    # library, projection or cluster
    assert out[-3].split() == ["pandas", "pyarrow", "numba"]
    assert out[-2] == "0"
