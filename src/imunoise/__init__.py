"""imunoise: online stochastic error modelling of inertial sensors with the GMWM.

Model algebra: ``2 * AR1() + WN() + RW()``; wavelet variance: :func:`wavelet_variance`;
estimator: :func:`gmwm`. All quantities are SI; GMWM parameters are per sample (SPEC §1).
"""

from __future__ import annotations

from typing import Any

from imunoise.errors import DataError, FitError, ImunoiseError, ModelError, UnitError
from imunoise.model import Model, StateSpace
from imunoise.processes import AR1, DR, QN, RW, WN

__version__ = "0.1.0"

__all__ = [
    "AR1",
    "DR",
    "QN",
    "RW",
    "WN",
    "Model",
    "StateSpace",
    "wavelet_variance",
    "WVAccumulator",
    "WaveletVariance",
    "gmwm",
    "GMWMFit",
    "select_model",
    "refit",
    "ImunoiseError",
    "DataError",
    "ModelError",
    "UnitError",
    "FitError",
    "__version__",
]

_LAZY = {
    "wavelet_variance": "imunoise.wv",
    "WVAccumulator": "imunoise.wv",
    "WaveletVariance": "imunoise.wv",
    "gmwm": "imunoise.gmwm",
    "GMWMFit": "imunoise.gmwm",
    "select_model": "imunoise.selection",
    "refit": "imunoise.selection",
}


def __getattr__(name: str) -> Any:
    # Lazy so that `import imunoise` stays fast (numba/scipy work happens on first use).
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'imunoise' has no attribute {name!r}")
