"""First-order moving average, MA1 (simts' MA1): x_t = e_t + θe_{t−1}, Var(e) = σ², per sample
(docs/guide/theory.rst, 'Latent processes').

Haar WV ν²(τ) = σ²[(1+θ)²τ − 6θ]/τ² (the Haar filter of width τ sees γ(0) = σ²(1+θ²) on its τ taps and
γ(1) = σ²θ on its τ − 1 neighbouring pairs, one of which straddles the sign change). Over scales longer than a
sample an MA1 is white with the density σ|1+θ|√Δt, which is how the filter and the (N, K) pair see it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.errors import ModelError
from imunoise.noise.process_base import LOG_HI, LOG_LO, EquivalentPart, Process

__all__ = ["MA1"]


@njit(cache=True, inline="always")
def _ma1_wv_u(u, p, tau, nu, jac):  # pragma: no cover - compiled
    th = math.tanh(u[p])  # θ in (−1, 1): invertible MA1
    s2 = math.exp(u[p + 1])
    for j in range(tau.shape[0]):
        t = tau[j]
        d = s2 * ((1.0 + th) ** 2 * t - 6.0 * th) / (t * t)
        nu[j] += d
        jac[j, p] += s2 * (2.0 * (1.0 + th) * t - 6.0) / (t * t) * (1.0 - th * th)
        jac[j, p + 1] += d


@njit(cache=True, inline="always")
def _ma1_wv_theta(theta, p, tau, nu):  # pragma: no cover - compiled
    for j in range(tau.shape[0]):
        t = tau[j]
        nu[j] += theta[p + 1] * ((1.0 + theta[p]) ** 2 * t - 6.0 * theta[p]) / (t * t)


class MA1(Process):
    """First-order moving average x_t = e_t + θe_{t−1}, Var(e) = σ² (simts' MA1):
    ν² = σ²[(1+θ)²τ − 6θ]/τ²; white at long scales with density N = σ|1+θ|√Δt.

    Parameters
    ----------
    theta : float, optional
        θ in (−1, 1) (invertible).
    sigma2 : float, optional
        σ² [u²], the innovation variance per sample. Give both or neither.
    """

    kind = "MA1"
    param_names = ("theta", "sigma2")
    param_units = ("1", "u^2")
    continuous_units = {"theta": "1", "noise_density": "u/√Hz"}

    def _validate(self, values):
        th, s2 = values
        if not -1.0 < th < 1.0:
            raise ModelError(f"MA1.theta must be in (-1, 1) for an invertible MA1, got {th}")
        if s2 < 0:
            raise ModelError(f"MA1.sigma2 must be ≥ 0, got {s2}")

    def wv(self, tau, values=None):
        th, s2 = values or self.values
        tau = np.asarray(tau, dtype=float)
        return s2 * ((1.0 + th) ** 2 * tau - 6.0 * th) / tau**2

    def wv_jacobian(self, tau, values=None):
        th, s2 = values or self.values
        tau = np.asarray(tau, dtype=float)
        d_theta = s2 * (2.0 * (1.0 + th) * tau - 6.0) / tau**2
        return np.column_stack([d_theta, ((1.0 + th) ** 2 * tau - 6.0 * th) / tau**2])

    def simulate(self, n, rng):
        th, s2 = self.values
        e = rng.normal(0.0, math.sqrt(s2), n + 1)
        return e[1:] + th * e[:-1]

    def continuous(self, freq, prefix="MA1"):
        th, s2 = self.values
        return {f"{prefix}.theta": th, f"{prefix}.noise_density": math.sqrt(s2 * (1.0 + th) ** 2 / freq)}

    @classmethod
    def u_bounds(cls, first):
        return [-20.0, LOG_LO], [20.0, LOG_HI]

    @classmethod
    def theta_from_u(cls, u, p, theta, scale, chain):
        theta[p] = math.tanh(u[p])
        theta[p + 1] = math.exp(u[p + 1]) * scale
        return chain

    @classmethod
    def u_from_theta(cls, theta, p, u, scale, chain):
        u[p] = math.atanh(min(max(theta[p], -1.0 + 1e-15), 1.0 - 1e-15))
        u[p + 1] = math.log(max(theta[p + 1] / scale, 1e-300))
        return chain

    def at_rate(self, freq_from, freq_to):
        th, s2 = self.values  # a one-sample correlation: kept as is, the white density N kept
        return MA1(theta=th, sigma2=s2 * (freq_to / freq_from))

    def white_variance(self):
        th, s2 = self.values
        return s2 * (1.0 + th) ** 2  # the filter sees its zero-frequency density

    @classmethod
    def start_values(cls, frac, nu, tau):
        return [0.0, frac * nu[0] * tau[0]]  # uncorrelated start, the finest scale's white level

    def equivalent_part(self, name, freq, white_below, horizon_s, qn, model_text):
        return EquivalentPart(self.white_variance(), 0.0, False, "N",
                              "one-sample correlation: white with its zero-frequency density sigma*|1+theta|")

    def spectrum(self, f, sin2):
        th, s2 = self.values
        return s2 * ((1.0 + th) ** 2 - 4.0 * th * sin2)


MA1.nb_wv_u, MA1.nb_wv_theta = _ma1_wv_u, _ma1_wv_theta
