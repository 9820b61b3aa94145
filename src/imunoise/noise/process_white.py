"""White processes (docs/guide/theory.rst, 'Latent processes'): Gaussian white noise WN (ν² = σ²/τ) and quantization
noise QN (ν² = 6Q²/τ²),
each with its numba forms right above it (the protocol: :class:`imunoise.noise.process_base.Process`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.noise.process_base import EquivalentPart, Process

__all__ = ["WN", "QN"]

# numba forms (the estimator's kernels call them; tests check them against wv): nb_wv_u(u, p, tau, nu, jac) adds
# ν and ∂ν/∂u of the component whose u starts at index p (normalised scale); nb_wv_theta(theta, p, tau, nu) adds
# ν from natural parameters. The registry (kind codes, canonical order) is :mod:`imunoise.noise.processes`.


@njit(cache=True, inline="always")
def _wn_wv_u(u, p, tau, nu, jac):  # pragma: no cover - compiled
    val = math.exp(u[p])
    for j in range(tau.shape[0]):
        d = val / tau[j]
        nu[j] += d
        jac[j, p] += d

@njit(cache=True, inline="always")
def _wn_wv_theta(theta, p, tau, nu):  # pragma: no cover - compiled
    for j in range(tau.shape[0]):
        nu[j] += theta[p] / tau[j]


class WN(Process):
    """Gaussian white noise, variance σ² per sample: ν² = σ²/τ; noise density N = σ√Δt.

    Parameters
    ----------
    sigma2 : float, optional
        σ² [u²] per sample; omit it for a process to be estimated.
    """

    kind = "WN"
    em_form = "observation"
    param_names = ("sigma2",)
    param_units = ("u^2",)
    continuous_units = {"noise_density": "u/√Hz"}

    def wv(self, tau, values=None):
        (s2,) = values or self.values
        return s2 / np.asarray(tau, dtype=float)

    def wv_jacobian(self, tau, values=None):
        return (1.0 / np.asarray(tau, dtype=float))[:, None]

    def simulate(self, n, rng):
        return rng.normal(0.0, math.sqrt(self.values[0]), n)

    def continuous(self, freq, prefix="WN"):
        return {f"{prefix}.noise_density": math.sqrt(self.values[0] / freq)}

    def at_rate(self, freq_from, freq_to):
        return WN(sigma2=self.values[0] * (freq_to / freq_from))  # N² = σ²/f

    def white_variance(self):
        return self.values[0]

    @classmethod
    def start_values(cls, frac, nu, tau):
        return [frac * nu[0] * tau[0]]

    def scaled(self, white, bias):
        return WN(sigma2=self.values[0] * white)

    def equivalent_part(self, name, freq, white_below, horizon_s, qn, model_text):
        return EquivalentPart(self.values[0], 0.0, False, "N", "white, exact: N = sigma*sqrt(dt)")

    def spectrum(self, f, sin2):
        return self.values[0]


@njit(cache=True, inline="always")
def _qn_wv_u(u, p, tau, nu, jac):  # pragma: no cover - compiled
    val = math.exp(u[p])
    for j in range(tau.shape[0]):
        t = tau[j]
        d = 6.0 * val / (t * t)
        nu[j] += d
        jac[j, p] += d

@njit(cache=True, inline="always")
def _qn_wv_theta(theta, p, tau, nu):  # pragma: no cover - compiled
    for j in range(tau.shape[0]):
        t = tau[j]
        nu[j] += 6.0 * theta[p] / (t * t)


class QN(Process):
    """Quantisation noise Q² (docs/guide/theory.rst, 'Latent processes'): x_t = u_t − u_{t−1}, Var(u) = Q²; ν² = 6Q²/τ²;
    Q_IEEE = QΔt.

    Parameters
    ----------
    q2 : float, optional
        Q² [u²]; omit it for a process to be estimated.
    """

    kind = "QN"
    param_names = ("q2",)
    param_units = ("u^2",)
    continuous_units = {"q_ieee": "u·s"}

    def wv(self, tau, values=None):
        (q2,) = values or self.values
        return 6.0 * q2 / np.asarray(tau, dtype=float) ** 2

    def wv_jacobian(self, tau, values=None):
        return (6.0 / np.asarray(tau, dtype=float) ** 2)[:, None]

    def simulate(self, n, rng):
        a = math.sqrt(3.0 * self.values[0])  # uniform on [−a, a] has variance a²/3
        u = rng.uniform(-a, a, n + 1)
        return np.diff(u)

    def continuous(self, freq, prefix="QN"):
        return {f"{prefix}.q_ieee": math.sqrt(self.values[0]) / freq}

    def at_rate(self, freq_from, freq_to):
        return QN(q2=self.values[0] * (freq_to / freq_from) ** 2)  # Q_IEEE = Q/f

    def white_variance(self):
        return 2.0 * self.values[0]  # x_t = u_t − u_{t−1} treated as white

    @classmethod
    def start_values(cls, frac, nu, tau):
        return [frac * nu[0] * tau[0] ** 2 / 6.0]

    def equivalent_part(self, name, freq, white_below, horizon_s, qn, model_text):
        if qn == "white":
            return EquivalentPart(2.0 * self.values[0], 0.0, False, "N", "white with its per-sample variance 2Q^2")
        return EquivalentPart(0.0, 0.0, False, "-", "dropped (qn='drop')")

    def spectrum(self, f, sin2):
        return 4.0 * self.values[0] * sin2  # x_t = u_t − u_{t−1}


WN.nb_wv_u, WN.nb_wv_theta = _wn_wv_u, _wn_wv_theta
QN.nb_wv_u, QN.nb_wv_theta = _qn_wv_u, _qn_wv_theta
