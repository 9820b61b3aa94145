"""Additive in-motion error terms of a motion law (:mod:`imunoise.sim.motion`, issue 21 §1): pure functions of
the static mask, the sample times and a random generator. Per axis j of :data:`imunoise.imu.AXES` (SI units:
rad/s for the gyros, m/s² for the accelerometers), sample k at time t_k, Δt = 1/f:

* moving Gauss–Markov (``moving_gm``): a first-order Gauss–Markov bias that evolves only while the vehicle
  moves and is frozen at stops; with φ_j = exp(−Δt/τ_j),

      x_{j,k} = φ_j x_{j,k−1} + σ_j √(1 − φ_j²) ε_{j,k}   (k moving),     x_{j,k} = x_{j,k−1}   (k static),

  x_{j,0} ~ N(0, σ_j²): stationary, so Var x_{j,k} = σ_j² at every k and, over moving samples only, the
  autocorrelation is exp(−|Δt_moving|/τ_j);
* departure step (``departure_step``): at every start from a stop (sample k static → k+1 moving) a bias step
  s ~ N(0, σ_j²) is added and kept, b_{j,k} = Σ_{departures i ≤ k} s_{j,i} (mounting and thermal shocks);
* warm-up (``warmup``): a deterministic bias from power-on (the first sample, t_0), an IMU warming up,

      b_j(t) = A_j (1 − exp(−(t − t_0)/τ)).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

__all__ = ["moving_gauss_markov", "departure_steps", "warmup_bias", "departures"]


def departures(static_mask: np.ndarray) -> np.ndarray:
    """Indices k of the first moving sample after each stop (static at k − 1, moving at k)."""
    s = np.asarray(static_mask, dtype=bool)
    return np.flatnonzero(s[:-1] & ~s[1:]) + 1


def moving_gauss_markov(static_mask: np.ndarray, rate_hz: float, sigma: np.ndarray, tau_s: np.ndarray,
                        rng: np.random.Generator) -> np.ndarray:
    """(n, m) moving Gauss–Markov paths (module docstring), one column per entry of ``sigma``/``tau_s``
    (columns with σ = 0 are zero; their draws are still made, so the stream does not depend on which axes
    carry the term). Draws: x_0 (m values), then one innovation row per moving sample."""
    s = np.asarray(static_mask, dtype=bool)
    sigma = np.asarray(sigma, dtype=float)
    tau = np.asarray(tau_s, dtype=float)
    m = sigma.size
    x0 = rng.standard_normal(m)
    mv = ~s
    e = rng.standard_normal((int(mv.sum()), m))
    out = np.zeros((s.size, m))
    for j in range(m):
        if sigma[j] == 0.0:
            continue
        phi = math.exp(-1.0 / (tau[j] * rate_hz))
        path = lfilter([1.0], [1.0, -phi], sigma[j] * math.sqrt(1.0 - phi * phi) * e[:, j],
                       zi=[phi * sigma[j] * x0[j]])[0]
        held = np.concatenate([[sigma[j] * x0[j]], path])
        out[:, j] = held[np.cumsum(mv)]  # static samples keep the last moving value (x_0 before any motion)
    return out


def departure_steps(static_mask: np.ndarray, sigma: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(n, m) step biases: N(0, σ²) added at each departure (:func:`departures`) and kept."""
    sigma = np.asarray(sigma, dtype=float)
    k = departures(static_mask)
    steps = rng.standard_normal((k.size, sigma.size)) * sigma
    jump = np.zeros((np.asarray(static_mask).size, sigma.size))
    jump[k] = steps
    return np.cumsum(jump, axis=0)


def warmup_bias(t: np.ndarray, amplitude: np.ndarray, tau_s: float) -> np.ndarray:
    """(n, m) warm-up bias A (1 − exp(−(t − t_0)/τ)), t_0 the first sample (power-on)."""
    t = np.asarray(t, dtype=float)
    return -np.expm1(-(t - t[0]) / tau_s)[:, None] * np.asarray(amplitude, dtype=float)[None, :]
