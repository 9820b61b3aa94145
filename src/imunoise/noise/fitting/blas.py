"""One BLAS thread while a GMWM fit runs: :func:`one_blas_thread`.

A fit's matrices are J×J with J ≈ 10–20 wavelet levels. OpenBLAS (numpy's and scipy's wheels) may still
split such a call over its threads, and waking them costs far more than the arithmetic: measured on a loaded
2-core machine, one 15×15 ``scipy.linalg.solve_triangular`` took 8 ms CPU with the default threads against
0.01 ms with one, and the three modelling jobs of the online run on ``data/drive_0708`` 1.13 s against 0.87 s.
The numbers are the same to the bit (the thread split partitions the outputs, not the sums; checked on the
fitted values of those jobs). The thread count is process-wide in OpenBLAS, so this sets it to one while at
least one fit runs (nested and concurrent fits share one setting) and puts the previous count back when the
last one ends. Without a loaded OpenBLAS that offers the call (other BLAS, other platforms) it does nothing.
"""

from __future__ import annotations

import ctypes
import functools
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

__all__ = ["one_blas_thread", "with_one_blas_thread"]

_LOCK = threading.Lock()
_DEPTH = 0
_PREVIOUS: list[int] = []
_SETTERS: list[Any] | None = None

F = TypeVar("F", bound=Callable[..., Any])


def _setters() -> list[Any]:
    """``openblas_set_num_threads_local`` of every OpenBLAS mapped into this process (Linux: /proc/self/maps)."""
    global _SETTERS
    if _SETTERS is None:
        found = []
        try:
            import scipy.linalg  # noqa: F401 - maps scipy's OpenBLAS (the one numba's LAPACK calls use)

            with open("/proc/self/maps", encoding="utf-8", errors="replace") as fh:
                paths = sorted({ln.split()[-1] for ln in fh if "openblas" in ln.lower() and "/" in ln})
            for path in paths:
                fn = getattr(ctypes.CDLL(path), "openblas_set_num_threads_local", None)
                if fn is not None:
                    fn.argtypes = [ctypes.c_int]
                    fn.restype = ctypes.c_int
                    found.append(fn)
        except (OSError, ImportError):
            found = []
        _SETTERS = found
    return _SETTERS


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with OpenBLAS limited to one thread (module docstring); the previous count comes back."""
    global _DEPTH, _PREVIOUS
    setters = _setters()
    if not setters:
        yield
        return
    with _LOCK:
        if _DEPTH == 0:
            _PREVIOUS = [fn(1) for fn in setters]
        _DEPTH += 1
    try:
        yield
    finally:
        with _LOCK:
            _DEPTH -= 1
            if _DEPTH == 0:
                for fn, n in zip(setters, _PREVIOUS):
                    fn(max(int(n), 1))


def with_one_blas_thread(func: F) -> F:
    """Decorator form of :func:`one_blas_thread`."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with one_blas_thread():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
