"""The first-order Gauss–Markov process AR1 (docs/guide/theory.rst, 'Latent processes'): x_k = φ x_{k−1} + w_k, w ~ N(0,
σ²), its Haar WV in
closed form (:mod:`imunoise.noise.ar1_math`) and its numba form in natural parameters (the u-form is chained by the
ordering of the AR1s, in the estimator's kernel, :mod:`imunoise.noise.fitting.kernels`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.errors import ModelError
from imunoise.noise.ar1_math import ar1_g, ar1_wv, ar1_wv_dphi
from imunoise.noise.process_base import (
    B_HI,
    B_LO,
    LOG_HI,
    LOG_LO,
    ROLE_STATIONARY,
    V_HI,
    V_LO,
    EquivalentPart,
    FilterState,
    Process,
    ar1_white_variance,
    fmt_seconds,
)

__all__ = ["AR1"]

# numba forms (the estimator's kernels call them; tests check them against wv): nb_wv_u(u, p, tau, nu, jac) adds
# ν and ∂ν/∂u of the component whose u starts at index p (normalised scale); nb_wv_theta(theta, p, tau, nu) adds
# ν from natural parameters. The registry (kind codes, canonical order) is :mod:`imunoise.noise.processes`.


@njit(cache=True, inline="always")
def _ar1_wv_theta(theta, p, tau, nu):  # pragma: no cover - compiled
    for j in range(tau.shape[0]):
        g, _ = ar1_g(tau[j] / 2.0, math.log(theta[p]))
        nu[j] += theta[p + 1] * g


class AR1(Process):
    """First-order autoregression (discrete Gauss–Markov) x_t = φx_{t−1} + e_t, Var(e) = σ².

    Continuous equivalents: T_c = −Δt/ln φ, σ²_GM = σ²/(1−φ²), q_c = 2σ²_GM/T_c
    (docs/guide/theory.rst, 'Latent processes').

    Parameters
    ----------
    phi : float, optional
        φ in (0, 1).
    sigma2 : float, optional
        σ² [u²], the innovation variance per sample. Give both or neither (a process to be estimated).
    """

    kind = "AR1"
    em_form = "state"
    reading = "gauss_markov"
    param_names = ("phi", "sigma2")
    param_units = ("1", "u^2")
    continuous_units = {"tau_c": "s", "sigma_gm": "u", "q_c": "u²/s"}

    def _validate(self, values):
        phi, s2 = values
        if not 0.0 < phi < 1.0:
            raise ModelError(
                f"AR1.phi must be in (0, 1) for a stationary positive-correlation AR1, got {phi}"
            )
        if s2 < 0:
            raise ModelError(f"AR1.sigma2 must be ≥ 0, got {s2}")

    def wv(self, tau, values=None):
        phi, s2 = values or self.values
        return ar1_wv(tau, phi, s2)

    def wv_jacobian(self, tau, values=None):
        phi, s2 = values or self.values
        return np.column_stack([ar1_wv_dphi(tau, phi, s2), ar1_wv(tau, phi, 1.0)])

    def simulate(self, n, rng):
        # imported here: scipy.signal costs ~0.5 s to import, and every `imunoise nav` run loads this module
        from scipy.signal import lfilter

        phi, s2 = self.values
        e = rng.normal(0.0, math.sqrt(s2), n)
        x0 = rng.normal(0.0, math.sqrt(s2 / (1.0 - phi * phi)))  # stationary start
        out, _ = lfilter([1.0], [1.0, -phi], e, zi=[phi * x0])
        return out

    def continuous(self, freq, prefix="AR1"):
        phi, s2 = self.values
        tau_c = -1.0 / (freq * math.log(phi))
        var_gm = s2 / (1.0 - phi * phi)
        return {
            f"{prefix}.tau_c": tau_c,
            f"{prefix}.sigma_gm": math.sqrt(var_gm),
            f"{prefix}.q_c": 2.0 * var_gm / tau_c,
        }

    singleton = False

    @classmethod
    def u_bounds(cls, first):
        return [V_LO if first else B_LO, LOG_LO], [V_HI if first else B_HI, LOG_HI]

    @classmethod
    def theta_from_u(cls, u, p, theta, scale, chain):
        # log(−ln φ) ordered: v_1 = u, v_k = v_{k−1} + exp(u_k), so φ_1 > φ_2 > … (no label switching)
        v = u[p] if chain is None else chain + math.exp(u[p])
        phi = math.exp(-math.exp(min(v, V_HI + 1.0)))
        theta[p] = min(max(phi, 1e-300), 1.0 - 1e-16)
        theta[p + 1] = math.exp(u[p + 1]) * scale
        return v

    @classmethod
    def u_from_theta(cls, theta, p, u, scale, chain):
        # a scalar clamp, not np.clip: the selection converts every start of every candidate (same bits, NaN kept)
        phi = min(max(float(theta[p]), 1e-300), 1.0 - 1e-15)
        v = math.log(-math.log(phi))
        if chain is None:
            u[p] = v
        else:
            u[p] = math.log(max(v - chain, 1e-9))
            v = chain + math.exp(u[p])
        u[p + 1] = math.log(max(theta[p + 1] / scale, 1e-300))
        return v

    def at_rate(self, freq_from, freq_to):
        phi, s2 = self.values
        phi_to = math.exp(math.log(phi) * (freq_from / freq_to))  # T_c = −1/(f ln φ) kept
        var_gm = s2 / (1.0 - phi * phi)
        return AR1(phi=phi_to, sigma2=var_gm * (1.0 - phi_to * phi_to))  # σ²_GM kept

    def filter_block(self, steps, dt):
        phi, s2 = self.values
        var_gm = s2 / (1.0 - phi * phi)
        phi_dt = math.exp(steps * math.log(phi))
        return 0.0, [FilterState(phi_dt, var_gm * (1.0 - phi_dt * phi_dt), var_gm, 1.0, ROLE_STATIONARY)]

    def scaled(self, white, bias):
        return AR1(phi=self.values[0], sigma2=self.values[1] * bias)

    def equivalent_part(self, name, freq, white_below, horizon_s, qn, model_text):
        phi, s2 = self.values
        tc = -(1.0 / freq) / math.log(phi)
        if tc <= white_below:
            return EquivalentPart(ar1_white_variance(phi, s2), 0.0, False, "N",
                                  f"T_c = {fmt_seconds(tc)} <= {fmt_seconds(white_below)}: white, density "
                                  "sigma/(1-phi)*sqrt(dt) (-> sigma_GM*sqrt(2*T_c) for T_c >> dt)")
        if horizon_s is not None and tc >= horizon_s:
            how = f"T_c = {fmt_seconds(tc)} >= horizon: a random walk of its innovation over the range; matched"
            return EquivalentPart(0.0, 0.0, True, "K", how)
        how = (f"T_c = {fmt_seconds(tc)} inside the range: white beyond T_c, random walk below; matched, "
               "its AV bump is what a WN+RW pair cannot follow")
        return EquivalentPart(0.0, 0.0, True, "N+K", how)

    def spectrum(self, f, sin2):
        phi, sig2 = self.values
        # 1 − 2φcos(2πf) + φ² written without cancellation (near φ → 1, f → 0 it is tiny, not 0)
        return sig2 / ((1.0 - phi) ** 2 + 4.0 * phi * sin2)

    def correlation_time(self, freq):
        return -1.0 / (freq * math.log(self.values[0]))


AR1.nb_wv_u, AR1.nb_wv_theta = None, _ar1_wv_theta  # AR1's u-form is chained (ordering), in the estimator's kernel
