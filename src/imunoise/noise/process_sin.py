"""A sinusoid, SIN (simts' SIN(alpha2, beta)): x_t = α sin(βt + U), U uniform on [0, 2π), per sample
(docs/guide/theory.rst, 'Latent processes'). A narrowband line such as an engine's or a rotor's vibration seen by
the IMU; α² [u²] the squared amplitude, β [rad/sample] in (0, π) the angular frequency (f = βF/(2π) Hz at the data
rate F).

Haar WV. The autocovariance is γ(h) = (α²/2) cos(βh), so ν²(τ) = (α²/2)|H_τ(β)|², H_τ the Haar filter of width τ
(τ/2 taps of +1/τ, τ/2 of −1/τ; white noise: σ²/τ), whose squared gain is 4 sin⁴(βτ/4)/(τ² sin²(β/2)):

    ν²(τ) = 2α² sin⁴(βτ/4) / (τ² sin²(β/2)).

At τ = 2 this is α² sin²(β/2)/2, the variance of (x_t − x_{t−1})/2. It rises as τ² below the period, peaks near
τ ≈ 4.66/β (tan(βτ/4) = βτ/2) and falls as 1/τ² beyond it, with the sin⁴ ripple of the dyadic scales. simts
parametrises its SIN by (alpha2, beta) (SMAC-Group/simts, the gen_sin/SIN test script); its stored
``src/process_to_wv.cpp`` has no SIN branch, so the closed form above is derived here, from γ(h), and checked
against simulation (tests/noise/test_process_sin.py, docs/evidence/sinusoid_process.md).

Filter. x = (α sin θ_t, α cos θ_t) with θ_t = βt + U rotates by b = β·steps per filter step:
Φ = [[cos b, sin b], [−sin b, cos b]], Q = 0, P0 = (α²/2)I, h = (1, 0): a 2-state oscillator
(:class:`~imunoise.noise.process_base.StateBlock`) that the fit→filter door keeps as it is. Q = 0 because the
process is a pure line: the filter learns its phase and then follows it.

EM: refused in one line (no first-order state with a closed-form M-step for β). Exports: a line has no share of
the white noise N or the random walk K, and a Kalibr/VIO file cannot carry it; the route says so.
Model selection: a candidate only when the complete model names it (``--complete "WN+RW+SIN"``); its spectrum is a
line, zero on the WVIC's continuous frequency grid.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.errors import ModelError
from imunoise.noise.process_base import LOG_HI, LOG_LO, ROLE_STATIONARY, EquivalentPart, Process, StateBlock

__all__ = ["SIN"]

_U_BETA = 25.0  # β = π/(1 + e^{−u}) with |u| ≤ 25: β from 4e-11 π to π(1 − 1.4e-11)
_PEAK = 4.0 * 1.1655611852072114  # βτ at the peak of sin⁴(βτ/4)/τ²: x = βτ/4 solves tan x = 2x


@njit(cache=True, inline="always")
def _sin_wv_u(u, p, tau, nu, jac):  # pragma: no cover - compiled
    a2 = math.exp(u[p])
    beta = math.pi / (1.0 + math.exp(-u[p + 1]))
    dbeta = beta * (1.0 - beta / math.pi)
    s = math.sin(0.5 * beta)
    c = math.cos(0.5 * beta)
    for j in range(tau.shape[0]):
        t = tau[j]
        S = math.sin(0.25 * beta * t)
        C = math.cos(0.25 * beta * t)
        d = 2.0 * a2 * S**4 / (t * t * s * s)
        nu[j] += d
        jac[j, p] += d
        jac[j, p + 1] += 2.0 * a2 / (t * t) * (S**3 * C * t / (s * s) - S**4 * c / s**3) * dbeta


@njit(cache=True, inline="always")
def _sin_wv_theta(theta, p, tau, nu):  # pragma: no cover - compiled
    s = math.sin(0.5 * theta[p + 1])
    for j in range(tau.shape[0]):
        t = tau[j]
        nu[j] += 2.0 * theta[p] * math.sin(0.25 * theta[p + 1] * t) ** 4 / (t * t * s * s)


def _gain(tau: np.ndarray, beta: float) -> np.ndarray:
    """ν²(τ)/α² = 2 sin⁴(βτ/4)/(τ² sin²(β/2))."""
    return 2.0 * np.sin(0.25 * beta * tau) ** 4 / (tau * tau * math.sin(0.5 * beta) ** 2)


class SIN(Process):
    """A sinusoid x_t = α sin(βt + U), U uniform (simts' SIN): ν² = 2α² sin⁴(βτ/4)/(τ² sin²(β/2)).

    Parameters
    ----------
    alpha2 : float, optional
        α² [u²], the squared amplitude (the process' variance is α²/2).
    beta : float, optional
        β [rad/sample] in (0, π): f = β·F/(2π) Hz at the data rate F. Give both or neither.
    """

    kind = "SIN"
    param_names = ("alpha2", "beta")
    param_units = ("u^2", "rad")
    continuous_units = {"amplitude": "u", "frequency": "Hz"}
    em_form = ""  # refused: no first-order state with a closed-form M-step for β (imunoise.noise.em)
    keeps_filter_state = True  # the door keeps its 2-state oscillator (module docstring)

    def _validate(self, values):
        a2, beta = values
        if a2 < 0:
            raise ModelError(f"SIN.alpha2 must be ≥ 0, got {a2}")
        if not 0.0 < beta < math.pi:
            raise ModelError(f"SIN.beta must be in (0, π) rad/sample (below the Nyquist frequency), got {beta}")

    def wv(self, tau, values=None):
        a2, beta = values or self.values
        return a2 * _gain(np.asarray(tau, dtype=float), beta)

    def wv_jacobian(self, tau, values=None):
        a2, beta = values or self.values
        tau = np.asarray(tau, dtype=float)
        S, C = np.sin(0.25 * beta * tau), np.cos(0.25 * beta * tau)
        s, c = math.sin(0.5 * beta), math.cos(0.5 * beta)
        d_beta = 2.0 * a2 / tau**2 * (S**3 * C * tau / s**2 - S**4 * c / s**3)
        return np.column_stack([_gain(tau, beta), d_beta])

    def identification_jacobian(self, tau):
        # ∂ν/∂β vanishes with α²: counted at α² = 1 so that a collapsed amplitude still has rank 2
        return SIN(alpha2=1.0, beta=self.values[1]).wv_jacobian(tau)

    def simulate(self, n, rng):
        a2, beta = self.values
        phase = rng.uniform(0.0, 2.0 * math.pi)
        return math.sqrt(a2) * np.sin(beta * np.arange(n) + phase)

    def continuous(self, freq, prefix="SIN"):
        a2, beta = self.values
        return {f"{prefix}.amplitude": math.sqrt(a2), f"{prefix}.frequency": beta * freq / (2.0 * math.pi)}

    @classmethod
    def u_bounds(cls, first):
        return [LOG_LO, -_U_BETA], [LOG_HI, _U_BETA]

    @classmethod
    def theta_from_u(cls, u, p, theta, scale, chain):
        theta[p] = math.exp(u[p]) * scale
        theta[p + 1] = math.pi / (1.0 + math.exp(-u[p + 1]))
        return chain

    @classmethod
    def u_from_theta(cls, theta, p, u, scale, chain):
        u[p] = math.log(max(theta[p] / scale, 1e-300))
        x = min(max(theta[p + 1] / math.pi, 1e-300), 1.0 - 1e-16)
        u[p + 1] = math.log(x / (1.0 - x))
        return chain

    @classmethod
    def start_values(cls, frac, nu, tau):
        # β from the WV's shape: on a grid of β, the least-squares fit (relative residuals) of the empirical WV by
        # the line plus a white (1/τ) and a random-walk-like (τ) background; the β that fits best, and α² so that
        # the line carries ``frac`` of its fitted share. A line's WV peaks at βτ ≈ 4.66 and ripples beyond, so a
        # start read off one scale lands on the wrong lobe; the grid sees every scale. Beyond βτ/4 = 2π the ripple
        # is replaced by its mean (sin⁴ → 3/8): there a 1 % change of β turns the ripple's phase by radians, and
        # the scales' few coefficients weigh little in the estimator, so the grid follows the envelope.
        nu = np.asarray(nu, dtype=float)
        tau = np.asarray(tau, dtype=float)
        best = (math.inf, _PEAK / tau[0], frac * nu[0])
        grid = np.geomspace(max(1.0 / tau[-1], 1e-6), 3.1, 240)
        for _ in range(2):  # the grid, then a finer one around its best
            for beta in grid:
                g = _gain(tau, float(beta))
                far = 0.25 * beta * tau > 2.0 * math.pi
                g[far] = 0.75 / (tau[far] ** 2 * math.sin(0.5 * beta) ** 2)
                A = np.column_stack([g, 1.0 / tau, tau]) / nu[:, None]
                coef = np.maximum(np.linalg.lstsq(A, np.ones(tau.size), rcond=None)[0], 0.0)
                res = float(np.sum((A @ coef - 1.0) ** 2))
                if coef[0] > 0 and res < best[0]:
                    best = (res, float(beta), float(coef[0]))
            grid = best[1] * np.geomspace(0.95, min(1.05, 3.1 / best[1]), 41)
        return [frac * best[2], best[1]]

    @classmethod
    def negligible(cls):
        return cls(alpha2=1e-300, beta=1.0)  # zero amplitude; β anywhere inside (0, π) keeps the WV finite

    def at_rate(self, freq_from, freq_to):
        a2, beta = self.values
        beta_to = beta * freq_from / freq_to  # the same frequency in Hz, the same amplitude
        if not beta_to < math.pi:
            raise ModelError(f"SIN at {beta * freq_from / (2 * math.pi):.4g} Hz is above the Nyquist frequency of "
                             f"{freq_to:g} Hz; keep the data rate, or fit without the line "
                             "(imunoise fit suppresses it by default)")
        return SIN(alpha2=a2, beta=beta_to)

    def filter_block(self, steps, dt):
        a2, beta = self.values
        b = beta * steps
        cb, sb = math.cos(b), math.sin(b)
        v = 0.5 * a2
        return 0.0, StateBlock(((cb, sb), (-sb, cb)), ((0.0, 0.0), (0.0, 0.0)), ((v, 0.0), (0.0, v)), (1.0, 0.0),
                               ROLE_STATIONARY)

    def equivalent_part(self, name, freq, white_below, horizon_s, qn, model_text):
        a2, beta = self.values
        return EquivalentPart(0.0, 0.0, False, "-",
                              f"a line at {beta * freq / (2 * math.pi):.4g} Hz, amplitude {math.sqrt(a2):.3g}: no "
                              "share of N or K; a VIO/Kalibr file cannot carry it (notch the line, or fit without it: "
                              "imunoise fit suppresses lines unless --keep-lines)")


SIN.nb_wv_u, SIN.nb_wv_theta = _sin_wv_u, _sin_wv_theta
