"""One BLAS thread inside the block kernels.

The kernels call BLAS on small dense blocks (6 x 6 up to a few hundred rows) from numba,
thousands of times per factorisation.  A multi-threaded BLAS wakes its threads for every
call; measured on a 2-core machine with a 1,000-photo block, the bundle adjustment took
2.8-7.5 s with OpenBLAS's default threads and 0.95 s with one.  The limit is applied only
while a kernel runs and restored afterwards.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TypeVar

from threadpoolctl import ThreadpoolController

F = TypeVar("F", bound=Callable)


@functools.lru_cache(maxsize=1)
def _controller() -> ThreadpoolController:
    return ThreadpoolController()


def single_threaded_blas(func: F) -> F:
    """Decorator: run `func` with BLAS limited to one thread."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with _controller().limit(limits=1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


class one_kernel_thread:
    """Context: numba's parallel kernels on one thread (the serial kernels), for work that is
    parallel across processes already (the trials of a study on a pool or a cluster); numba's
    thread count is restored at the end."""

    def __enter__(self):
        import numba

        self._before = numba.get_num_threads()
        numba.set_num_threads(1)
        return self

    def __exit__(self, *exc) -> None:
        import numba

        numba.set_num_threads(self._before)
