"""imunoise: online stochastic error modelling of inertial sensors with the GMWM.

Model algebra: ``2 * AR1() + WN() + RW()``; wavelet variance: :func:`wavelet_variance` (of a long log fed in
chunks: :class:`WVStream`);
estimators: :func:`gmwm` (GMWM), :func:`refit`, :func:`em_fit` (EM baseline), all called as
``estimator(model, data, freq=...)``, and :func:`select_model`; :func:`warm_up` compiles (or loads from
numba's cache) the fitting kernels ahead of the first fit (the online engine calls it at construction); the
command ``imunoise warm-up`` (what ``make`` runs) compiles the kernels of every command. All quantities are
SI; GMWM parameters are per sample (docs/guide/theory.rst, 'Conventions').

No exported name equals a submodule's name (the estimator lives in :mod:`imunoise.noise.estimator`): an
exported function and a submodule of the same name share one attribute of this package, and importing
the submodule replaces the function with the module.

Layout along the data path IMU → detection → modelling → filter: :mod:`imunoise.io` reads records into SI
arrays; :mod:`imunoise.detect` finds the static intervals; the modelling core :mod:`imunoise.noise` (processes
and their algebra, the wavelet variance, the GMWM estimator, model selection, the Allan and EM baselines) turns
the data into error models; :mod:`imunoise.nav` filters with them, and :mod:`imunoise.online` runs the whole path while
the data arrive. :mod:`imunoise.sim`, :mod:`imunoise.experiments` and :mod:`imunoise.cli` sit on top. A
stage imports only earlier stages (and :mod:`imunoise.errors`, :mod:`imunoise.units`,
:mod:`imunoise.report`), never a later one (tests/test_docs.py checks it).
"""

from __future__ import annotations

from typing import Any

from imunoise._version import __version__
from imunoise.errors import DataError, FitError, ImunoiseError, ModelError, UnitError
from imunoise.noise.moved import install as _install_moved

_install_moved()  # the modelling core's old import paths (imunoise.model, ...) for one release

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
    "AR1": "imunoise.noise.model",  # via the model, which registers the algebra
    "DR": "imunoise.noise.model",  # via the model, which registers the algebra
    "QN": "imunoise.noise.model",  # via the model, which registers the algebra
    "RW": "imunoise.noise.model",  # via the model, which registers the algebra
    "WN": "imunoise.noise.model",  # via the model, which registers the algebra
    "Model": "imunoise.noise.model",
    "StateSpace": "imunoise.noise.model",
    "as_model": "imunoise.noise.model",
    "wavelet_variance": "imunoise.noise.wv",
    "WVAccumulator": "imunoise.noise.wv",
    "WVStream": "imunoise.noise.wv_stream",
    "WaveletVariance": "imunoise.noise.wv",
    "gmwm": "imunoise.noise.estimator",
    "GMWMFit": "imunoise.noise.estimator",
    "select_model": "imunoise.noise.selection",
    "refit": "imunoise.noise.estimator",
    "em_fit": "imunoise.noise.em",
    "warm_up": "imunoise.noise.fitting.warm",
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

        importlib.import_module("imunoise.noise.model")  # registers the processes' algebra
        registry = importlib.import_module("imunoise.noise.processes").PROCESS_TYPES
        if name in registry:
            globals()[name] = registry[name]
            return registry[name]
    raise AttributeError(f"module 'imunoise' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
