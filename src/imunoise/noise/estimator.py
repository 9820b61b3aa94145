"""Generalized Method of Wavelet Moments (paper Eq. 6, docs/guide/theory.rst, 'GMWM estimator'): the documented import
path.

θ̂ = argmin_θ (ν̂ − ν(θ))ᵀ Ω (ν̂ − ν(θ)). The implementation lives in :mod:`imunoise.noise.fitting`, one
concept per module (parametrisation, compiled kernels, problem set-up, result, estimators); this module
re-exports its public names:

* estimators: :func:`gmwm`, :func:`refit` (also importable from :mod:`imunoise.noise.selection`),
  :func:`fit_problem` on a :class:`GMWMProblem` from :func:`prepare`;
* the result :class:`GMWMFit` and its reporting helpers :func:`band_departures`, :func:`departures_text`,
  :func:`unit_text`, :data:`PARAM_UNITS`, :data:`CONTINUOUS_UNITS`;
* argument checks :func:`check_freq`, :func:`check_unit`; kind codes :data:`KIND_CODE`.
"""

from __future__ import annotations

from imunoise.noise.fitting.arguments import check_freq, check_unit
from imunoise.noise.fitting.estimate import fit_problem, gmwm, refit
from imunoise.noise.fitting.params import KIND_CODE
from imunoise.noise.fitting.problem import GMWMProblem, prepare
from imunoise.noise.fitting.result import (
    CONTINUOUS_UNITS,
    PARAM_UNITS,
    GMWMFit,
    band_departures,
    departures_text,
    unit_text,
)

__all__ = [
    "gmwm",
    "refit",
    "GMWMFit",
    "GMWMProblem",
    "prepare",
    "fit_problem",
    "check_freq",
    "check_unit",
    "band_departures",
    "departures_text",
    "unit_text",
    "KIND_CODE",
    "PARAM_UNITS",
    "CONTINUOUS_UNITS",
]
