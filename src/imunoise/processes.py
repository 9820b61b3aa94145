"""Latent stochastic processes of inertial sensor errors and their Haar wavelet variance (SPEC §2).

Each process is per sample at the data rate f = 1/Δt (the convention of R's simts). The closed forms
below are the Haar MODWT wavelet variance ν²(τ) at scale τ = τ_j = 2^j samples (SPEC §1):

=====  ==========  ==========================================================================
WN     σ²          σ²/τ
QN     Q²          6Q²/τ²
RW     γ²          γ²(τ² + 2)/(12τ)
DR     ω           ω²τ²/16
AR1    φ, σ²       σ²[τ/2 − 3φ − (τ/2)φ² + 4φ^{τ/2+1} − φ^{τ+1}] / [2(τ/2)²(1−φ)²(1−φ²)]
MA1    θ, σ²       σ²[(1+θ)²τ − 6θ]/τ²  (:mod:`imunoise.process_ma1`)
=====  ==========  ==========================================================================

Each class owns its math (the protocol: :class:`imunoise.process_base.Process`); its numba forms, which the
estimator's kernels run, sit right above it. Everything else iterates over :data:`PROCESS_TYPES`, the one kind
vocabulary (``cls.code`` is the compiled kind code).

A process either has all its parameters (a "known" process, e.g. ``AR1(phi=0.99, sigma2=1e-6)``) or
none (``AR1()``, to be estimated). ``+`` and ``k *`` build a :class:`imunoise.model.Model`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.ar1_math import ar1_g, ar1_wv, ar1_wv_dphi
from imunoise.errors import ModelError
from imunoise.process_base import (
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
    ar1_white_variance,
    dr_equivalent_rw,
    fmt_seconds,
)
from imunoise.process_ma1 import MA1

__all__ = [
    "Process", "WN", "QN", "RW", "DR", "AR1", "MA1", "PROCESS_TYPES", "ORDER", "N_PARAMS", "ar1_wv", "ar1_wv_dphi",
    "ROLE_BIAS", "ROLE_STATIONARY", "ROLE_RAMP", "FilterState", "EquivalentPart", "dr_equivalent_rw",
    "ar1_white_variance", "LOG_LO", "LOG_HI", "V_LO", "V_HI", "B_LO", "B_HI",
]

# numba forms (the estimator's kernels call them; tests check them against wv): nb_wv_u(u, p, tau, nu, jac) adds
# ν and ∂ν/∂u of the component whose u starts at index p (normalised scale); nb_wv_theta(theta, p, tau, nu) adds
# ν from natural parameters.


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
    """Quantisation noise Q² (SPEC §2): x_t = u_t − u_{t−1}, Var(u) = Q²; ν² = 6Q²/τ²; Q_IEEE = QΔt.

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


@njit(cache=True, inline="always")
def _ar1_wv_theta(theta, p, tau, nu):  # pragma: no cover - compiled
    for j in range(tau.shape[0]):
        g, _ = ar1_g(tau[j] / 2.0, math.log(theta[p]))
        nu[j] += theta[p + 1] * g


class AR1(Process):
    """First-order autoregression (discrete Gauss–Markov) x_t = φx_{t−1} + e_t, Var(e) = σ².

    Continuous equivalents: T_c = −Δt/ln φ, σ²_GM = σ²/(1−φ²), q_c = 2σ²_GM/T_c (SPEC §2).

    Parameters
    ----------
    phi : float, optional
        φ in (0, 1).
    sigma2 : float, optional
        σ² [u²], the innovation variance per sample. Give both or neither (a process to be estimated).
    """

    kind = "AR1"
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
        phi = float(np.clip(theta[p], 1e-300, 1.0 - 1e-15))
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


for _cls, _u, _t in ((WN, _wn_wv_u, _wn_wv_theta), (QN, _qn_wv_u, _qn_wv_theta), (RW, _rw_wv_u, _rw_wv_theta),
                     (DR, _dr_wv_u, _dr_wv_theta), (AR1, None, _ar1_wv_theta)):
    _cls.nb_wv_u, _cls.nb_wv_theta = _u, _t  # AR1's u-form is chained (ordering), in the estimator's kernel

PROCESS_TYPES: dict[str, type[Process]] = {cls.kind: cls for cls in (AR1, WN, QN, RW, DR, MA1)}
"""The registry, the one kind vocabulary: canonical order (a model lists its components in it) and, by position,
the compiled kind codes. A new process is one class above plus its entry here (and its branch in the kernels'
dispatch, :mod:`imunoise.fitting.kernels`)."""
for _code, _cls in enumerate(PROCESS_TYPES.values()):
    _cls.code = _code
ORDER: tuple[str, ...] = tuple(PROCESS_TYPES)
N_PARAMS: tuple[int, ...] = tuple(len(c.param_names) for c in PROCESS_TYPES.values())
