"""``njit(cache=True)`` that degrades gracefully where numba cannot cache.

Numba writes its cache next to the module (``__pycache__``) or under ``NUMBA_CACHE_DIR``; when
neither is writable (read-only installs, some CI runners) ``njit(cache=True)`` raises at
decoration time. :func:`kernel` then compiles in memory instead and warns once.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

from numba import njit

__all__ = ["kernel", "parallel_kernel"]

_warned = False


def kernel(fn: Callable[..., Any], **options: Any) -> Callable[..., Any]:
    """Decorate ``fn`` with ``numba.njit(cache=True)``, falling back to ``cache=False``."""
    global _warned
    try:
        return njit(cache=True, **options)(fn)
    except RuntimeError as exc:  # "cannot cache function ...: no locator available"
        if not _warned:
            warnings.warn(
                f"numba cannot cache compiled kernels ({exc}); compiling in memory. Set "
                "NUMBA_CACHE_DIR to a writable folder to avoid recompiling in every process.",
                RuntimeWarning,
                stacklevel=2,
            )
            _warned = True
        return njit(cache=False, **options)(fn)


def parallel_kernel(fn: Callable[..., Any]) -> Callable[..., Any]:
    """:func:`kernel` with ``parallel=True`` (``numba.prange`` loops run on numba's threads)."""
    return kernel(fn, parallel=True)
