"""imunoise: online stochastic error modelling of inertial sensors with the GMWM.

Model algebra: ``2 * AR1() + WN() + RW()``; wavelet variance: :func:`wavelet_variance` (of a long log fed in
chunks: :class:`WVStream`);
estimators: :func:`gmwm` (GMWM), :func:`refit`, :func:`em_fit` (EM baseline), all called as
``estimator(model, data, freq=...)``, and :func:`select_model`; :func:`warm_up` compiles (or loads from
numba's cache) the fitting kernels ahead of the first fit (the online engine calls it at construction); the
command ``imunoise warm-up`` (what ``make`` runs) compiles the kernels of every command. All quantities are
SI; GMWM parameters are per sample (docs/guide/theory.rst, 'Conventions').

No exported name equals a submodule's name (the estimator lives in :mod:`imunoise.estimator`): an
exported function and a submodule of the same name share one attribute of this package, and importing
the submodule replaces the function with the module.

Layout along the data path IMU → detection → modelling → filter: :mod:`imunoise.io` reads records into SI
arrays; :mod:`imunoise.detect` finds the static intervals; the modelling core (:mod:`~imunoise.processes`,
:mod:`~imunoise.model`, :mod:`~imunoise.wv`, :mod:`~imunoise.estimator` on :mod:`imunoise.fitting`,
:mod:`~imunoise.selection`, baselines :mod:`~imunoise.allan` and :mod:`~imunoise.em`) turns the data into
error models; :mod:`imunoise.nav` filters with them, and :mod:`imunoise.online` runs the whole path while
the data arrive. :mod:`imunoise.sim`, :mod:`imunoise.experiments` and :mod:`imunoise.cli` sit on top. A
stage imports only earlier stages (and :mod:`imunoise.errors`, :mod:`imunoise.units`,
:mod:`imunoise.report`), never a later one (tests/test_docs.py checks it).
"""

from __future__ import annotations

from typing import Any

from imunoise._version import __version__
from imunoise.errors import DataError, FitError, ImunoiseError, ModelError, UnitError

__all__ = [
    "AR1",
    "DR",
    "QN",
    "RW",
    "WN",
    "Model",
    "StateSpace",
    "as_model",
    "wavelet_variance",
    "WVAccumulator",
    "WVStream",
    "WaveletVariance",
    "gmwm",
    "GMWMFit",
    "select_model",
    "refit",
    "em_fit",
    "warm_up",
    "ImunoiseError",
    "DataError",
    "ModelError",
    "UnitError",
    "FitError",
    "__version__",
]

# Everything that needs numpy/scipy is imported on first use: `import imunoise` (and so `imunoise --help`,
# which imports the package before its CLI) loads only the error classes.
_LAZY = {
    "AR1": "imunoise.model",  # via the model, which registers the algebra
    "DR": "imunoise.model",  # via the model, which registers the algebra
    "QN": "imunoise.model",  # via the model, which registers the algebra
    "RW": "imunoise.model",  # via the model, which registers the algebra
    "WN": "imunoise.model",  # via the model, which registers the algebra
    "Model": "imunoise.model",
    "StateSpace": "imunoise.model",
    "as_model": "imunoise.model",
    "wavelet_variance": "imunoise.wv",
    "WVAccumulator": "imunoise.wv",
    "WVStream": "imunoise.wv_stream",
    "WaveletVariance": "imunoise.wv",
    "gmwm": "imunoise.estimator",
    "GMWMFit": "imunoise.estimator",
    "select_model": "imunoise.selection",
    "refit": "imunoise.estimator",
    "em_fit": "imunoise.em",
    "warm_up": "imunoise.fitting.warm",
}


def __getattr__(name: str) -> Any:
    # Lazy so that `import imunoise` stays fast (numba/scipy work happens on first use). The value is
    # cached as a real attribute, so later lookups do not come back here.
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    if name.isalnum() and name.isupper():  # a process of the registry beyond the five above, e.g. imunoise.MA1
        import importlib

        importlib.import_module("imunoise.model")  # registers the processes' algebra
        registry = importlib.import_module("imunoise.processes").PROCESS_TYPES
        if name in registry:
            globals()[name] = registry[name]
            return registry[name]
    raise AttributeError(f"module 'imunoise' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
