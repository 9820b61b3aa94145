"""Unconstrained parametrisation of a GMWM model (paper Eq. 6 solved as least squares, SPEC §4).

* variances (σ², Q², γ²) and the drift ``|ω|`` as logarithms, divided by the data's WV scale c (ω by √c);
* AR1s through their correlation times, ordered: v_k = log(−ln φ_k) with v_1 = u and
  v_k = v_{k−1} + exp(u_k), so φ_1 > φ_2 > … (slowest first) and labels never switch.
"""

from __future__ import annotations

import math

import numpy as np

from imunoise.model import Model

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
]

KIND_CODE = {"AR1": 0, "WN": 1, "QN": 2, "RW": 3, "DR": 4}

LOG_LO, LOG_HI = -120.0, 40.0  # normalised log-variance bounds (e^-120: indistinguishable from 0)
V_LO, V_HI = -32.0, 4.0  # log(−ln φ): φ from 1 − 1.3e-14 down to e^-55
B_LO, B_HI = -30.0, 4.0  # log spacing between successive AR1 correlation scales


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
    return np.array([KIND_CODE[c.kind] for c in model.components], dtype=np.int64)


def bounds(kinds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds of u for the Levenberg–Marquardt solver (module docstring).

    Parameters
    ----------
    kinds
        Kind codes of the components (:func:`kind_codes`).

    Returns
    -------
    lo, hi : numpy.ndarray
        Lower and upper bounds of every entry of u (normalised scale).
    """
    lo, hi = [], []
    first = True
    for k in kinds:
        if k == 0:
            lo += [V_LO if first else B_LO, LOG_LO]
            hi += [V_HI if first else B_HI, LOG_HI]
            first = False
        else:
            lo.append(LOG_LO / (2 if k == 4 else 1))
            hi.append(LOG_HI / (2 if k == 4 else 1))
    return np.array(lo), np.array(hi)


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
        θ in :attr:`imunoise.model.Model.vector` order (φ, σ² per AR1; σ², Q², γ², ω per process).
    """
    theta = np.empty_like(u)
    p = 0
    v = 0.0
    first = True
    for k in kinds:
        if k == 0:
            v = u[p] if first else v + math.exp(u[p])
            first = False
            phi = math.exp(-math.exp(min(v, V_HI + 1.0)))
            theta[p] = min(max(phi, 1e-300), 1.0 - 1e-16)
            theta[p + 1] = math.exp(u[p + 1]) * scale
            p += 2
        elif k == 4:
            theta[p] = math.exp(u[p]) * math.sqrt(scale)
            p += 1
        else:
            theta[p] = math.exp(u[p]) * scale
            p += 1
    return theta


def theta_to_u(theta: np.ndarray, kinds: np.ndarray, scale: float) -> np.ndarray:
    """Inverse of :func:`u_to_theta`, clipped to :func:`bounds`.

    Parameters
    ----------
    theta
        Natural parameters in :attr:`imunoise.model.Model.vector` order; AR1s sorted by decreasing φ
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
    u = np.empty_like(theta, dtype=float)
    p = 0
    v_prev = None
    for k in kinds:
        if k == 0:
            phi = float(np.clip(theta[p], 1e-300, 1.0 - 1e-15))
            v = math.log(-math.log(phi))
            if v_prev is None:
                u[p] = v
            else:
                u[p] = math.log(max(v - v_prev, 1e-9))
                v = v_prev + math.exp(u[p])
            v_prev = v
            u[p + 1] = math.log(max(theta[p + 1] / scale, 1e-300))
            p += 2
        elif k == 4:
            u[p] = math.log(max(abs(theta[p]) / math.sqrt(scale), 1e-150))
            p += 1
        else:
            u[p] = math.log(max(theta[p] / scale, 1e-300))
            p += 1
    lo, hi = bounds(kinds)
    return np.clip(u, lo, hi)
