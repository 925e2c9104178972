"""The numba decorator falls back to in-memory compilation when caching is impossible."""

from __future__ import annotations

import pytest
from numba import njit

from baarda.linalg import _jit


def test_kernel_without_cache_locator(monkeypatch):
    def fake_njit(cache=False):
        if cache:
            raise RuntimeError("cannot cache function 'f': no locator available for file 'x'")
        return njit(cache=False)

    monkeypatch.setattr(_jit, "njit", fake_njit)
    monkeypatch.setattr(_jit, "_warned", False)

    def f(x):
        return 2 * x

    with pytest.warns(RuntimeWarning, match="compiling in memory"):
        g = _jit.kernel(f)
    assert g(21) == 42
