"""``njit(cache=True)`` that works wherever baarda is installed, and knows when the first
compile is still to come.

Numba caches compiled kernels beside their module (``__pycache__``), else in the user's
cache folder, or under ``NUMBA_CACHE_DIR``.  Where none is writable (a read-only install
and no writable HOME) ``njit(cache=True)`` raises "no locator available"; :func:`kernel`
then points numba at a private folder in the temporary directory
(``baarda-numba-<uid>``) and caches there, and only if even that fails compiles in memory.
:func:`is_cached` tells whether a kernel still has to be compiled (its cache index is
missing): a kernel without one takes the package's compiled code where it fits this
installation (linalg/kernel_bundle.py), and linalg/precompile.py compiles the rest before the
first, slow run.
"""

from __future__ import annotations

import os
import pickle
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from numba import njit
from numba.core import config

__all__ = ["is_cached", "is_fresh", "kernel", "parallel_kernel"]

# every cached kernel of the package (numba dispatchers): the compile table is recorded from them
KERNELS: list[Any] = []


def fallback_cache_dir() -> Path:
    """The private cache folder in the temporary directory (created, mode 0700)."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    path = Path(tempfile.gettempdir()) / f"baarda-numba-{uid}"
    path.mkdir(mode=0o700, exist_ok=True)
    return path


def kernel(fn: Callable[..., Any], **options: Any) -> Callable[..., Any]:
    """``numba.njit(cache=True)``; where numba finds no writable cache, a cache in the
    temporary directory; where that fails too, compiled in memory (with a warning)."""
    try:
        disp = njit(cache=True, **options)(fn)
    except RuntimeError as exc:  # "cannot cache function ...: no locator available"
        try:
            if config.CACHE_DIR:  # type: ignore[attr-defined]  # numba sets config at run time
                raise
            config.CACHE_DIR = str(fallback_cache_dir())  # type: ignore[attr-defined]
            disp = njit(cache=True, **options)(fn)
        except (RuntimeError, OSError):
            warnings.warn(f"numba cannot cache compiled kernels ({exc}); compiling in "
                          "memory in every run. Set NUMBA_CACHE_DIR to a writable folder.",
                          RuntimeWarning, stacklevel=2)
            return njit(cache=False, **options)(fn)
    KERNELS.append(disp)
    if not is_fresh(disp):  # a first run (no index: not fresh), or the source changed:
        from .kernel_bundle import seed  # the package's compiled code, where it fits

        seed(disp)
    return disp


def parallel_kernel(fn: Callable[..., Any]) -> Callable[..., Any]:
    """:func:`kernel` with ``parallel=True`` (``numba.prange`` loops run on numba's threads)."""
    return kernel(fn, parallel=True)


def is_fresh(disp: Any) -> bool:
    """Whether the kernel's cache index is numba's current one for its source file (written
    by this numba for the file's present stamp); False without an index (not is_cached),
    True where that cannot be told."""
    try:
        cf = disp._cache._cache_file
        with open(cf._index_path, "rb") as fh:
            version = pickle.load(fh)
            stamp = pickle.loads(fh.read())[0]
        return bool(version == cf._version and stamp == cf._source_stamp)
    except AttributeError:  # not a caching dispatcher, or numba's internals changed
        return True
    except (OSError, ValueError, EOFError, pickle.UnpicklingError, IndexError, TypeError):
        return False


def is_cached(disp: Any) -> bool:
    """Whether numba's cache holds compiled code of the kernel `disp` (its index file exists;
    True for a kernel that cannot be cached: there is nothing to compile ahead)."""
    try:
        return Path(disp._cache._cache_file._index_path).is_file()
    except AttributeError:  # not a caching dispatcher, or numba's internals changed
        return True
