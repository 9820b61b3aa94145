"""Latent stochastic processes of inertial sensor errors and their Haar wavelet variance (SPEC §2).

Each process is per sample at the data rate f = 1/Δt (the convention of R's simts). The closed forms
below are the Haar MODWT wavelet variance ν²(τ) at scale τ = τ_j = 2^j samples (SPEC §1):

=====  ==========  ==========================================================================
WN     σ²          σ²/τ
QN     Q²          6Q²/τ²
RW     γ²          γ²(τ² + 2)/(12τ)
DR     ω           ω²τ²/16
AR1    φ, σ²       σ²[τ/2 − 3φ − (τ/2)φ² + 4φ^{τ/2+1} − φ^{τ+1}] / [2(τ/2)²(1−φ)²(1−φ²)]
=====  ==========  ==========================================================================

A process either has all its parameters (a "known" process, e.g. ``AR1(phi=0.99, sigma2=1e-6)``) or
none (``AR1()``, to be estimated). ``+`` and ``k *`` build a :class:`imunoise.model.Model`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from imunoise.errors import ModelError

if TYPE_CHECKING:
    from imunoise.model import Model

__all__ = ["Process", "WN", "QN", "RW", "DR", "AR1", "PROCESS_TYPES", "ar1_wv", "ar1_wv_dphi"]


def _expm1_tail(x: np.ndarray, order: int) -> np.ndarray:
    """exp(x) − Σ_{n<order} xⁿ/n!, accurate for small |x| (order 2: expm1 − x; order 3: − x²/2 too).

    The AR1 closed form is a difference of powers of φ whose constant, linear and quadratic terms in
    log φ cancel exactly; writing it through these tails removes the catastrophic cancellation that the
    textbook form suffers for φ → 1 (e.g. φ = 0.9999 at τ = 2 loses ~12 digits otherwise).
    """
    x = np.asarray(x, dtype=float)
    out = np.empty_like(x)
    small = np.abs(x) < 0.5
    xs = x[small]
    term = xs**order / math.factorial(order)
    acc = term.copy()
    for n in range(order + 1, order + 30):
        term = term * xs / n
        acc += term
    out[small] = acc
    xl = x[~small]
    big = np.expm1(xl) - xl
    if order == 3:
        big = big - 0.5 * xl * xl
    out[~small] = big
    return out


def ar1_wv(tau: np.ndarray, phi: float, sigma2: float) -> np.ndarray:
    """Haar WV of a stationary AR1 with innovation variance σ² (SPEC §2 table, cancellation-free).

    With m = τ/2, L = ln φ and F_k = e^{kL} − 1 − kL − (kL)²/2 the numerator equals
    −3F_1 − mF_2 + 4F_{m+1} − F_{2m+1} exactly, and the denominator is 2m²(1−φ)²(1−φ²).
    """
    tau = np.asarray(tau, dtype=float)
    m = tau / 2.0
    L = math.log(phi)

    # Tails where (2m+1)|L| is small (the cancelling regime), plain expm1 elsewhere: there the tails
    # would subtract huge polynomial terms instead.
    def num_with(order: int) -> np.ndarray:
        def e(x: np.ndarray) -> np.ndarray:
            return _expm1_tail(x, order) if order else np.expm1(x)

        return (
            -3.0 * e(np.full_like(m, L))
            - m * e(np.full_like(m, 2 * L))
            + 4.0 * e((m + 1) * L)
            - e((2 * m + 1) * L)
        )

    small = np.abs((2 * m + 1) * L) < 1.0
    num = np.where(small, num_with(3), num_with(0))
    one_m_phi = -math.expm1(L)
    one_m_phi2 = -math.expm1(2 * L)
    den = 2.0 * m * m * one_m_phi**2 * one_m_phi2
    return sigma2 * num / den


def ar1_wv_dphi(tau: np.ndarray, phi: float, sigma2: float) -> np.ndarray:
    """∂ν²/∂φ of the AR1 Haar WV (analytic; same cancellation-free tails as :func:`ar1_wv`).

    g = N/D, N' = −2mG_1 + 4(m+1)G_m − (2m+1)G_{2m} with G_k = e^{kL} − 1 − kL, and
    D'/D = −2(1+2φ)/(1−φ²), so g' = N'/D + g·2(1+2φ)/(1−φ²).
    """
    tau = np.asarray(tau, dtype=float)
    m = tau / 2.0
    L = math.log(phi)

    def dnum_with(order: int) -> np.ndarray:
        def e(x: np.ndarray) -> np.ndarray:
            return _expm1_tail(x, order) if order else np.expm1(x)

        return -2.0 * m * e(np.full_like(m, L)) + 4.0 * (m + 1) * e(m * L) - (2 * m + 1) * e(2 * m * L)

    small = np.abs(2 * m * L) < 1.0
    dnum = np.where(small, dnum_with(2), dnum_with(0))
    one_m_phi = -math.expm1(L)
    one_m_phi2 = -math.expm1(2 * L)
    den = 2.0 * m * m * one_m_phi**2 * one_m_phi2
    g = ar1_wv(tau, phi, 1.0)
    return sigma2 * (dnum / den + g * 2.0 * (1.0 + 2.0 * phi) / one_m_phi2)


class Process:
    """One latent process; parameters per sample (SPEC §1). Subclasses define the closed forms.

    Parameters
    ----------
    **params : float, optional
        The values of :attr:`param_names`, all or none (none: unknown, to be estimated by :func:`~imunoise.gmwm`).
        ``u`` in the units is the data unit.

    Raises
    ------
    ModelError
        For an unknown name, only some parameters given, or a value out of range.
    """

    kind: ClassVar[str] = ""
    param_names: ClassVar[tuple[str, ...]] = ()
    param_units: ClassVar[tuple[str, ...]] = ()  # unit of each parameter, in terms of the data unit "u"

    def __init__(self, **params: float | None) -> None:
        unknown = set(params) - set(self.param_names)
        if unknown:
            raise ModelError(
                f"{self.kind} has no parameter(s) {sorted(unknown)}; "
                f"its parameters are {list(self.param_names)}"
            )
        values = [params.get(name) for name in self.param_names]
        if any(v is None for v in values) and any(v is not None for v in values):
            raise ModelError(f"{self.kind}: give all of {list(self.param_names)} or none of them")
        self._values: tuple[float, ...] | None = None
        if all(v is not None for v in values):
            vals = tuple(float(v) for v in values)  # type: ignore[arg-type]
            if not all(math.isfinite(v) for v in vals):
                raise ModelError(
                    f"{self.kind}: parameters must be finite, got {dict(zip(self.param_names, vals))}"
                )
            self._validate(vals)
            self._values = vals

    # -- parameters ---------------------------------------------------------------------------
    @property
    def known(self) -> bool:
        return self._values is not None

    @property
    def values(self) -> tuple[float, ...]:
        if self._values is None:
            raise ModelError(f"{self.kind} has unknown parameters; estimate them with gmwm() or give them")
        return self._values

    def with_values(self, values: tuple[float, ...] | list[float] | np.ndarray) -> Process:
        return type(self)(**dict(zip(self.param_names, (float(v) for v in values))))

    def unknown(self) -> Process:
        return type(self)()

    def _validate(self, values: tuple[float, ...]) -> None:
        for name, v in zip(self.param_names, values):
            if v < 0:
                raise ModelError(f"{self.kind}.{name} must be ≥ 0, got {v}")

    # -- closed forms ---------------------------------------------------------------------------
    def wv(self, tau: np.ndarray, values: tuple[float, ...] | None = None) -> np.ndarray:
        """Theoretical Haar WV at scales τ (samples)."""
        raise NotImplementedError

    def wv_jacobian(self, tau: np.ndarray, values: tuple[float, ...] | None = None) -> np.ndarray:
        """∂ν²(τ)/∂θ for the natural parameters θ, shape (len(τ), n_params)."""
        raise NotImplementedError

    def simulate(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` samples of the process from ``rng`` (a known process only)."""
        raise NotImplementedError

    def continuous(self, freq: float, prefix: str) -> dict[str, float]:
        """Continuous-time equivalents (SPEC §2 last column) in SI-style units of the data."""
        raise NotImplementedError

    # -- algebra ----------------------------------------------------------------------------------
    def __add__(self, other: Process | Model) -> Model:
        from imunoise.model import Model

        return Model([self]) + other

    def __radd__(self, other: object) -> Model:
        from imunoise.model import Model

        if other == 0:  # sum([...]) support
            return Model([self])
        return NotImplemented

    def __mul__(self, k: int) -> Model:
        from imunoise.model import Model

        if not isinstance(k, int) or isinstance(k, bool) or k < 1:
            raise ModelError(f"a process can be repeated a positive whole number of times, got {k!r}")
        return Model([self] * k)

    __rmul__ = __mul__

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self._values == other._values  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash((self.kind, self._values))

    def __repr__(self) -> str:
        if self._values is None:
            return f"{self.kind}()"
        args = ", ".join(f"{n}={v:.6g}" for n, v in zip(self.param_names, self._values))
        return f"{self.kind}({args})"


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

    def wv(self, tau, values=None):
        (s2,) = values or self.values
        return s2 / np.asarray(tau, dtype=float)

    def wv_jacobian(self, tau, values=None):
        return (1.0 / np.asarray(tau, dtype=float))[:, None]

    def simulate(self, n, rng):
        return rng.normal(0.0, math.sqrt(self.values[0]), n)

    def continuous(self, freq, prefix="WN"):
        return {f"{prefix}.noise_density": math.sqrt(self.values[0] / freq)}


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


class RW(Process):
    """Random walk with innovation variance γ²: ν² = γ²(τ² + 2)/(12τ); K = γ/√Δt.

    Parameters
    ----------
    gamma2 : float, optional
        γ² [u²] per sample; omit it for a process to be estimated.
    """

    kind = "RW"
    param_names = ("gamma2",)
    param_units = ("u^2",)

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


class DR(Process):
    """Deterministic drift (rate ramp) ω per sample: x_t = ω·t; ν² = ω²τ²/16; R = ω/Δt.

    The WV depends on ω² only, so GMWM returns ``|ω|`` (the sign is not identifiable from the WV).

    Parameters
    ----------
    omega : float, optional
        ω [u] per sample (any sign); omit it for a process to be estimated.
    """

    kind = "DR"
    param_names = ("omega",)
    param_units = ("u",)

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
    param_names = ("phi", "sigma2")
    param_units = ("1", "u^2")

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


PROCESS_TYPES: dict[str, type[Process]] = {cls.kind: cls for cls in (AR1, WN, QN, RW, DR)}
