"""Make ``helpers_linalg`` importable in every pytest import mode (incl. importlib)."""

import sys
from pathlib import Path

_HERE = str(Path(__file__).parent)
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)
