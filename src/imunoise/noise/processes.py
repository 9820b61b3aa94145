"""Latent stochastic processes of inertial sensor errors and their Haar wavelet variance
(docs/guide/theory.rst, 'Latent processes').

Each process is per sample at the data rate f = 1/Δt (the convention of R's simts). The closed forms
below are the Haar MODWT wavelet variance ν²(τ) at scale τ = τ_j = 2^j samples (docs/guide/theory.rst, 'Conventions'):

=====  ==========  ==========================================================================
WN     σ²          σ²/τ
QN     Q²          6Q²/τ²
RW     γ²          γ²(τ² + 2)/(12τ)
DR     ω           ω²τ²/16
AR1    φ, σ²       σ²[τ/2 − 3φ − (τ/2)φ² + 4φ^{τ/2+1} − φ^{τ+1}] / [2(τ/2)²(1−φ)²(1−φ²)]
MA1    θ, σ²       σ²[(1+θ)²τ − 6θ]/τ²  (:mod:`imunoise.noise.process_ma1`)
=====  ==========  ==========================================================================

Each class owns its math (the protocol: :class:`imunoise.noise.process_base.Process`); its numba forms, which the
estimator's kernels run, sit right above it in its family's module (:mod:`imunoise.noise.process_white`: WN, QN;
:mod:`imunoise.noise.process_bias`: RW, DR; :mod:`imunoise.noise.process_ar1`: AR1;
:mod:`imunoise.noise.process_ma1`: MA1).
Everything else iterates over :data:`PROCESS_TYPES`, the one kind vocabulary (``cls.code`` is the compiled kind
code), kept in :mod:`imunoise.noise.process_registry`.

A process either has all its parameters (a "known" process, e.g. ``AR1(phi=0.99, sigma2=1e-6)``) or
none (``AR1()``, to be estimated). ``+`` and ``k *`` build a :class:`imunoise.noise.model.Model`.
"""

from __future__ import annotations

from imunoise.noise.ar1_math import ar1_wv, ar1_wv_dphi
from imunoise.noise.process_ar1 import AR1
from imunoise.noise.process_base import (
    B_HI,
    B_LO,
    LOG_HI,
    LOG_LO,
    ROLE_BIAS,
    ROLE_RAMP,
    ROLE_STATIONARY,
    V_HI,
    V_LO,
    EquivalentPart,
    FilterState,
    Process,
    StateBlock,
    ar1_white_variance,
    dr_equivalent_rw,
)
from imunoise.noise.process_bias import DR, RW
from imunoise.noise.process_ma1 import MA1
from imunoise.noise.process_registry import N_PARAMS, ORDER, PROCESS_TYPES
from imunoise.noise.process_white import QN, WN

__all__ = [
    "Process", "WN", "QN", "RW", "DR", "AR1", "MA1", "PROCESS_TYPES", "ORDER", "N_PARAMS", "ar1_wv",
    "ar1_wv_dphi",
    "ROLE_BIAS", "ROLE_STATIONARY", "ROLE_RAMP", "FilterState", "StateBlock", "EquivalentPart", "dr_equivalent_rw",
    "ar1_white_variance", "LOG_LO", "LOG_HI", "V_LO", "V_HI", "B_LO", "B_HI",
]

# The sum type: loading the model sets Process.sum_type, so that WN() + RW() works from any import of the processes
# (the model imports the registry and the family modules, never this module: no cycle).
import imunoise.noise.model  # noqa: E402,F401


def __getattr__(name: str) -> type[Process]:
    # a process of the registry that has no import line above (a new one lives in its own module and its registry
    # line): ``from imunoise.noise.processes import KIND`` works for every registered kind
    if name in PROCESS_TYPES:
        return PROCESS_TYPES[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
