"""Keep ``scipy.linalg`` out of a command that needs no SciPy routine (issue "Performance where users wait":
`nav` whole process).

numba's CPU target, when it starts (the first kernel a process calls or loads from the cache), runs
``import scipy.linalg.cython_blas`` to check that BLAS is there (``numba.np.arraymath._check_blas``). That
import executes the whole ``scipy.linalg`` package first (its ``__init__`` pulls in scipy's array-API layer,
``_cythonized_array_utils``, the decompositions …): 0.2–0.3 s CPU, a sixth of a `nav --no-plots` run, for
nothing a kernel uses. :func:`defer_scipy_linalg` loads the ``cython_blas`` extension on its own (what numba
and its BLAS wrappers actually use: the function pointers in its ``__pyx_capi__``) and registers
``scipy.linalg`` as a lazy module (:class:`importlib.util.LazyLoader`): the package runs, complete and
unchanged, the first time anything touches it (an ``import scipy.linalg``, ``from scipy.linalg import …`` or
an attribute), so code that uses SciPy sees no difference. Nothing is done when ``scipy.linalg`` is already
imported, when SciPy is missing, or when its layout is not the expected one.

Not a command (no ``register``); it imports nothing heavy.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys

__all__ = ["defer_scipy_linalg"]


def defer_scipy_linalg() -> bool:
    """Register ``scipy.linalg`` lazily with its ``cython_blas`` already loaded (module docstring).

    Returns
    -------
    bool
        Whether the deferral is in place (False: ``scipy.linalg`` is imported already, or cannot be found, and
        nothing was changed).
    """
    if "scipy.linalg" in sys.modules or "scipy.linalg.cython_blas" in sys.modules:
        return False
    try:
        spec = importlib.util.find_spec("scipy.linalg")  # imports the light top-level `scipy` only
    except (ImportError, ValueError):
        return False
    if spec is None or spec.loader is None or not spec.submodule_search_locations:
        return False
    finder = importlib.machinery.FileFinder(
        spec.submodule_search_locations[0],
        (importlib.machinery.ExtensionFileLoader, importlib.machinery.EXTENSION_SUFFIXES),
    )
    blas_spec = finder.find_spec("scipy.linalg.cython_blas")
    if blas_spec is None or blas_spec.loader is None:
        return False
    blas = importlib.util.module_from_spec(blas_spec)
    blas_spec.loader.exec_module(blas)
    spec.loader = importlib.util.LazyLoader(spec.loader)
    linalg = importlib.util.module_from_spec(spec)
    sys.modules["scipy.linalg"] = linalg
    sys.modules["scipy.linalg.cython_blas"] = blas
    spec.loader.exec_module(linalg)  # deferred: runs on the first attribute access
    linalg.cython_blas = blas  # kept through the deferred run (LazyLoader re-applies attributes set before it)
    return True
