"""The numba decorator caches wherever baarda runs: numba's own places, else a private
folder in the temporary directory, else in memory (issue 15)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from numba import njit
from numba.core import config

from baarda.linalg import _jit

ROOT = Path(__file__).resolve().parents[2]


def test_kernel_compiles_in_memory_when_nothing_can_cache(monkeypatch):
    def fake_njit(cache=False):
        if cache:
            raise RuntimeError("cannot cache function 'f': no locator available for file 'x'")
        return njit(cache=False)

    monkeypatch.setattr(_jit, "njit", fake_njit)
    monkeypatch.setattr(config, "CACHE_DIR", "")
    monkeypatch.setattr(_jit, "fallback_cache_dir", lambda: (_ for _ in ()).throw(
        OSError("read-only /tmp")))

    def f(x):
        return 2 * x

    with pytest.warns(RuntimeWarning, match="compiling in memory"):
        g = _jit.kernel(f)
    assert g(21) == 42


@pytest.mark.slow
def test_no_writable_cache_falls_back_to_the_temporary_directory(tmp_path):
    """A process in which numba finds no cache locator (read-only install, no HOME): the
    kernels are cached under $TMPDIR/baarda-numba-<uid>, the first compile is announced and
    the adjustment runs; a second process finds the kernels compiled and says nothing."""
    script = (
        "import numba.core.caching as c\n"
        "c.CacheImpl._locator_classes = [c.UserProvidedCacheLocator]\n"  # NUMBA_CACHE_DIR only
        "from baarda.cli import main\n"
        "from numba.core import config\n"
        f"code = main(['adjust', {str(ROOT / 'examples' / 'demo')!r}, '-o', "
        f"{str(tmp_path / 'out')!r}])\n"
        "print(code, config.CACHE_DIR)\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    # the compile path: the package's compiled kernels (linalg/kernel_bundle.py) not used
    env.update(TMPDIR=str(tmp_path), HOME="/nonexistent", BAARDA_KERNEL_BUNDLE="0")
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       env=env, cwd=tmp_path, timeout=300)
    assert p.returncode == 0, p.stderr
    code, cache = p.stdout.split()[-2:]
    assert code == "0" and cache == str(tmp_path / f"baarda-numba-{os.getuid()}")
    assert list(Path(cache).rglob("*.nbi")), "nothing was cached"
    assert "Traceback" not in p.stderr and "RuntimeWarning" not in p.stderr
    first = p.stderr.splitlines()[0]  # the compile is said (a note: no terminal here)
    assert first.startswith("note: compiling the numerical kernels once")
    env["NUMBA_CACHE_DIR"] = cache
    second = subprocess.run([sys.executable, "-m", "baarda", "adjust",
                             str(ROOT / "examples" / "demo"), "-o", str(tmp_path / "b")],
                            capture_output=True, text=True, env=env, timeout=300)
    assert second.returncode == 0 and "compiling" not in second.stderr
