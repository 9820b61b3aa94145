"""Non-stationary bias processes (docs/guide/theory.rst, 'Latent processes'): the random walk RW (ν² = γ²(τ² + 2)/(12τ))
and the drift DR, a ramp of slope ω (ν² = ω²τ²/16), each with its numba forms right above it (the protocol:
:class:`imunoise.noise.process_base.Process`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.errors import ModelError
from imunoise.noise.process_base import (
    LOG_HI,
    LOG_LO,
    ROLE_RAMP,
    EquivalentPart,
    FilterState,
    Process,
    dr_equivalent_rw,
)

__all__ = ["RW", "DR"]

# numba forms (the estimator's kernels call them; tests check them against wv): nb_wv_u(u, p, tau, nu, jac) adds
# ν and ∂ν/∂u of the component whose u starts at index p (normalised scale); nb_wv_theta(theta, p, tau, nu) adds
# ν from natural parameters. The registry (kind codes, canonical order) is :mod:`imunoise.noise.processes`.


@njit(cache=True, inline="always")
def _rw_wv_u(u, p, tau, nu, jac):  # pragma: no cover - compiled
    val = math.exp(u[p])
    for j in range(tau.shape[0]):
        t = tau[j]
        d = val * (t * t + 2.0) / (12.0 * t)
        nu[j] += d
        jac[j, p] += d

@njit(cache=True, inline="always")
def _rw_wv_theta(theta, p, tau, nu):  # pragma: no cover - compiled
    for j in range(tau.shape[0]):
        t = tau[j]
        nu[j] += theta[p] * (t * t + 2.0) / (12.0 * t)


class RW(Process):
    """Random walk with innovation variance γ²: ν² = γ²(τ² + 2)/(12τ); K = γ/√Δt.

    Parameters
    ----------
    gamma2 : float, optional
        γ² [u²] per sample; omit it for a process to be estimated.
    """

    kind = "RW"
    em_form = "state"
    reading = "random_walk"
    param_names = ("gamma2",)
    param_units = ("u^2",)
    continuous_units = {"random_walk": "u/s/√Hz"}

    def wv(self, tau, values=None):
        (g2,) = values or self.values
        tau = np.asarray(tau, dtype=float)
        return g2 * (tau**2 + 2.0) / (12.0 * tau)

    def wv_jacobian(self, tau, values=None):
        tau = np.asarray(tau, dtype=float)
        return ((tau**2 + 2.0) / (12.0 * tau))[:, None]

    def simulate(self, n, rng):
        return np.cumsum(rng.normal(0.0, math.sqrt(self.values[0]), n))

    def continuous(self, freq, prefix="RW"):
        return {f"{prefix}.random_walk": math.sqrt(self.values[0] * freq)}

    def at_rate(self, freq_from, freq_to):
        return RW(gamma2=self.values[0] * (freq_from / freq_to))  # K² = γ²f

    def filter_block(self, steps, dt):
        return self.values[0] * steps, []

    starts_fine = False

    @classmethod
    def start_values(cls, frac, nu, tau):
        return [frac * nu[-1] * 12.0 * tau[-1] / (tau[-1] ** 2 + 2.0)]

    def scaled(self, white, bias):
        return RW(gamma2=self.values[0] * bias)

    def equivalent_part(self, name, freq, white_below, horizon_s, qn, model_text):
        return EquivalentPart(0.0, self.values[0], False, "K", "random walk, exact: K = gamma/sqrt(dt)")

    def spectrum(self, f, sin2):
        return self.values[0] / (4.0 * sin2)  # pseudo-spectrum; the Haar gain removes the pole


@njit(cache=True, inline="always")
def _dr_wv_u(u, p, tau, nu, jac):  # pragma: no cover - compiled
    val = math.exp(u[p])  # |ω|/√c: the WV is quadratic in it, so ∂ν/∂u = 2ν
    for j in range(tau.shape[0]):
        t = tau[j]
        d = val * val * t * t / 16.0
        jac[j, p] += 2.0 * d
        nu[j] += d

@njit(cache=True, inline="always")
def _dr_wv_theta(theta, p, tau, nu):  # pragma: no cover - compiled
    for j in range(tau.shape[0]):
        t = tau[j]
        nu[j] += theta[p] * theta[p] * t * t / 16.0


class DR(Process):
    """Deterministic drift (rate ramp) ω per sample: x_t = ω·t; ν² = ω²τ²/16; R = ω/Δt.

    The WV depends on ω² only, so GMWM returns ``|ω|`` (the sign is not identifiable from the WV).

    Parameters
    ----------
    omega : float, optional
        ω [u] per sample (any sign); omit it for a process to be estimated.
    """

    kind = "DR"
    em_form = "drift"
    reading = "ramp"
    param_names = ("omega",)
    param_units = ("u",)
    continuous_units = {"rate_ramp": "u/s"}

    def _validate(self, values):
        pass  # a drift may be negative

    def wv(self, tau, values=None):
        (w,) = values or self.values
        return w * w * np.asarray(tau, dtype=float) ** 2 / 16.0

    def wv_jacobian(self, tau, values=None):
        (w,) = values or self.values
        return (2.0 * w * np.asarray(tau, dtype=float) ** 2 / 16.0)[:, None]

    def simulate(self, n, rng):
        return self.values[0] * np.arange(1, n + 1, dtype=float)

    def continuous(self, freq, prefix="DR"):
        return {f"{prefix}.rate_ramp": self.values[0] * freq}

    @classmethod
    def u_bounds(cls, first):
        return [LOG_LO / 2], [LOG_HI / 2]

    @classmethod
    def theta_from_u(cls, u, p, theta, scale, chain):
        theta[p] = math.exp(u[p]) * math.sqrt(scale)  # ω scales as √c (the WV is quadratic in ω)
        return chain

    @classmethod
    def u_from_theta(cls, theta, p, u, scale, chain):
        u[p] = math.log(max(abs(theta[p]) / math.sqrt(scale), 1e-150))
        return chain

    def at_rate(self, freq_from, freq_to):
        return DR(omega=self.values[0] * (freq_from / freq_to))  # R = ωf

    starts_fine = False

    @classmethod
    def start_values(cls, frac, nu, tau):
        return [math.sqrt(frac * nu[-1] * 16.0) / tau[-1]]

    @classmethod
    def embedding(cls, frac, nu, tau):
        return DR(omega=max(cls.start_values(frac, nu, tau)[0], 1e-150))

    def filter_block(self, steps, dt):
        # a constant ramp state r (unit/s): bias_{k+1} = bias_k + r·dt
        return 0.0, [FilterState(1.0, 0.0, 0.0, 0.0, ROLE_RAMP, dt)]

    def equivalent_part(self, name, freq, white_below, horizon_s, qn, model_text):
        if horizon_s is None:
            raise ModelError(f"{model_text}: a DR maps to the random walk with its AV at the horizon; give horizon_s")
        return EquivalentPart(0.0, dr_equivalent_rw(self.values[0], 2.0 * float(horizon_s) * freq), False, "K",
                              "ramp: the random walk with the same AV at the horizon (on the scales of "
                              "the data a ramp and a random walk are two readings of one rising AV)")

    def identification_jacobian(self, tau):
        tau = np.asarray(tau, dtype=float)
        return (tau**2 / 16.0)[:, None]  # ∂ν/∂ω² never vanishes, unlike ∂ν/∂ω at ω = 0


RW.nb_wv_u, RW.nb_wv_theta = _rw_wv_u, _rw_wv_theta
DR.nb_wv_u, DR.nb_wv_theta = _dr_wv_u, _dr_wv_theta
