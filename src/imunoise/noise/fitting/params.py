"""Unconstrained parametrisation of a GMWM model (paper Eq. 6 solved as least squares,
docs/guide/theory.rst, 'GMWM estimator').

* variances (σ², Q², γ²) and the drift ``|ω|`` as logarithms, divided by the data's WV scale c (ω by √c);
* AR1s through their correlation times, ordered: v_k = log(−ln φ_k) with v_1 = u and
  v_k = v_{k−1} + exp(u_k), so φ_1 > φ_2 > … (slowest first) and labels never switch.

Each process class owns its entries (:meth:`imunoise.noise.processes.Process.u_bounds`, ``theta_from_u``,
``u_from_theta``); this module walks a model's components through them by kind code.
"""

from __future__ import annotations

import numpy as np

from imunoise.noise.model import Model
from imunoise.noise.processes import B_HI, B_LO, LOG_HI, LOG_LO, PROCESS_TYPES, V_HI, V_LO

__all__ = [
    "KIND_CODE",
    "LOG_LO",
    "LOG_HI",
    "V_LO",
    "V_HI",
    "B_LO",
    "B_HI",
    "kind_codes",
    "bounds",
    "u_to_theta",
    "theta_to_u",
    "thetas_to_u",
]

_TYPES = tuple(PROCESS_TYPES.values())
KIND_CODE = {cls.kind: cls.code for cls in _TYPES}
"""Compiled kind code of each process kind (from the registry :data:`imunoise.noise.processes.PROCESS_TYPES`)."""


def kind_codes(model: Model) -> np.ndarray:
    """Kind code (:data:`KIND_CODE`) of each component of ``model``, in its canonical order.

    Parameters
    ----------
    model
        A model; its parameters, if any, are not used.

    Returns
    -------
    numpy.ndarray of int64
        One code per component, the layout the compiled kernels read.
    """
    return np.array([c.code for c in model.components], dtype=np.int64)


def _plan(kinds: np.ndarray) -> tuple[tuple[tuple[type, int], ...], np.ndarray, np.ndarray]:
    """(process class, first entry) of each component and the bounds of u, computed once per structure:
    every candidate of a selection converts thousands of starts (the walk itself is the same)."""
    key = kinds.tobytes()
    plan = _PLANS.get(key)
    if plan is None:
        steps = []
        lo: list[float] = []
        hi: list[float] = []
        first = True
        p = 0
        for k in kinds.tolist():
            cls = _TYPES[k]
            steps.append((cls, p))
            p += len(cls.param_names)
            a, b = cls.u_bounds(first)
            lo += a
            hi += b
            first = first and cls.singleton
        plan = (tuple(steps), np.array(lo), np.array(hi))
        _PLANS[key] = plan
    return plan


_PLANS: dict[bytes, tuple[tuple[tuple[type, int], ...], np.ndarray, np.ndarray]] = {}


def bounds(kinds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds of u for the Levenberg–Marquardt solver (module docstring).

    Parameters
    ----------
    kinds
        Kind codes of the components (:func:`kind_codes`).

    Returns
    -------
    lo, hi : numpy.ndarray
        Lower and upper bounds of every entry of u (normalised scale); fresh arrays the caller may keep.
    """
    _, lo, hi = _plan(kinds)
    return lo.copy(), hi.copy()


def u_to_theta(u: np.ndarray, kinds: np.ndarray, scale: float) -> np.ndarray:
    """Natural parameters (canonical order, original units) from u.

    Parameters
    ----------
    u
        Unconstrained parameters (module docstring).
    kinds
        Kind codes of the components (:func:`kind_codes`).
    scale
        The normalisation c of the problem's WV (1.0: u is on the data's own scale).

    Returns
    -------
    numpy.ndarray
        θ in :attr:`imunoise.noise.model.Model.vector` order (φ, σ² per AR1; σ², Q², γ², ω per process).
    """
    theta = np.empty_like(u)
    chain = None
    for cls, p in _plan(kinds)[0]:
        chain = cls.theta_from_u(u, p, theta, scale, chain)
    return theta


def theta_to_u(theta: np.ndarray, kinds: np.ndarray, scale: float) -> np.ndarray:
    """Inverse of :func:`u_to_theta`, clipped to :func:`bounds`.

    Parameters
    ----------
    theta
        Natural parameters in :attr:`imunoise.noise.model.Model.vector` order; AR1s sorted by decreasing φ
        (ties are nudged apart).
    kinds
        Kind codes of the components (:func:`kind_codes`).
    scale
        The normalisation c of the problem's WV.

    Returns
    -------
    numpy.ndarray
        u, within the solver's bounds.
    """
    return thetas_to_u([theta], kinds, scale)[0]


def thetas_to_u(thetas: list, kinds: np.ndarray, scale: float) -> np.ndarray:
    """:func:`theta_to_u` of many parameter vectors of one structure, one row each (the same numbers).

    Parameters
    ----------
    thetas
        Natural parameter vectors (arrays or lists of floats), all of the structure ``kinds``.
    kinds
        Kind codes of the components (:func:`kind_codes`).
    scale
        The normalisation c of the problem's WV.

    Returns
    -------
    numpy.ndarray
        (len(thetas), P) array of u, within the solver's bounds.
    """
    from imunoise.noise.fitting.kernels import u_rows  # numba: imported when a fit runs, not with this module

    steps, lo, hi = _plan(kinds)
    P = len(lo)
    TH = np.array(thetas, dtype=float).reshape(len(thetas), P) if len(thetas) else np.empty((0, P))
    # the processes' walk below, compiled (the same bits; tests/noise/fitting/test_fitting_params.py compares them)
    U, ok = u_rows(TH, kinds, float(scale))
    if not ok:
        U = _u_rows_walk(TH, steps, P, scale)
    np.maximum(U, lo, out=U)
    return np.minimum(U, hi, out=U)


def _u_rows_walk(TH: np.ndarray, steps: tuple, P: int, scale: float) -> np.ndarray:
    """The rows of u through each process' ``u_from_theta`` (unclipped)."""
    convs = [(cls.u_from_theta, p) for cls, p in steps]
    rows = []
    for theta in TH:
        th = theta.tolist()
        u = [0.0] * P
        chain = None
        for conv, p in convs:
            chain = conv(th, p, u, scale, chain)
        rows.append(u)
    return np.array(rows, dtype=float).reshape(len(rows), P)
