"""One BLAS thread for identification's small linear algebra.

Identification solves hundreds of tiny least-squares problems (Gram matrices of 512 x 65,
non-negative least squares of 20 x 8, L-BFGS-B steps of 1-5 unknowns). A multi-threaded
OpenBLAS wakes its threads for each of them, and on a busy machine they wait for a core:
on the shared 2-core development machine at load 5, a 512 x 65 Gram matrix took 9.4 ms with
the default threads against 0.065 ms with one, and one 6 h axis's identification 0.88 s
against 0.43 s (tools/bench_identification.py, docs/identification.md "Speed and memory").
None of these matrices is large enough for a second thread to pay, so identification runs
with one, through threadpoolctl (the standard way to set a loaded BLAS's thread count at run
time); without threadpoolctl nothing is limited. The results are the same numbers to the
rounding of a summation order (1e-16 relative).
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Iterator
from functools import wraps
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])


@functools.cache
def _controller() -> Any:
    """threadpoolctl's view of the loaded BLAS libraries, made once (None without it).

    Finding them walks the process's shared objects: 1.4 ms, which each short record's
    Allan deviation paid when the limit was set by threadpool_limits() (the verdict draws
    hundreds); with the controller kept, setting the limit costs 10 us. numpy's and
    scipy's BLAS (the two identification calls) are loaded before it looks.
    """
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    import numpy  # noqa: F401  (its BLAS: np.dot)

    with contextlib.suppress(ImportError):
        import scipy.linalg  # noqa: F401  (its own BLAS: least squares, L-BFGS-B)
    return ThreadpoolController()


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """BLAS limited to one thread inside the block (no-op without threadpoolctl)."""
    controller = _controller()
    if controller is None:  # the limit is a speed-up only: run as the BLAS is set
        yield
        return
    with controller.limit(limits=1, user_api="blas"):
        yield


def with_one_blas_thread(function: F) -> F:
    """``function`` run inside ``one_blas_thread()``."""

    @wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with one_blas_thread():
            return function(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
