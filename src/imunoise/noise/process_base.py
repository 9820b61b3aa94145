"""The process protocol (docs/guide/theory.rst, 'Latent processes'): what every latent process of an error model
carries, and the shared types.

A process owns its math: its parameters and their bounds in the estimator's unconstrained vector u
(:meth:`Process.u_bounds`, :meth:`Process.theta_from_u`, :meth:`Process.u_from_theta`), its Haar WV in numpy
(:meth:`Process.wv`) and in numba (``nb_wv_u``/``nb_wv_theta``, written next to the class; tests check both
equal), its state-space block (:meth:`Process.filter_block`), its (N, K) route (:meth:`Process.equivalent_part`)
and its parameters at another sample rate (:meth:`Process.at_rate`). The processes themselves and their registry
(the one kind vocabulary): :mod:`imunoise.noise.processes`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

import numpy as np

from imunoise.errors import ModelError

if TYPE_CHECKING:  # the sum type is imunoise.noise.model.Model, which imports the processes (not the reverse)
    Model = Any

__all__ = [
    "Process", "ROLE_BIAS", "ROLE_STATIONARY", "ROLE_RAMP", "FilterState", "StateBlock", "EquivalentPart",
    "dr_equivalent_rw",
    "ar1_white_variance", "fmt_seconds", "LOG_LO", "LOG_HI", "V_LO", "V_HI", "B_LO", "B_HI",
]

# Bounds of the estimator's unconstrained vector u (docs/guide/theory.rst, 'GMWM estimator';
# imunoise.noise.fitting.params describes u).
LOG_LO, LOG_HI = -120.0, 40.0  # normalised log-variance bounds (e^-120: indistinguishable from 0)
V_LO, V_HI = -32.0, 4.0  # log(−ln φ): φ from 1 − 1.3e-14 down to e^-55
B_LO, B_HI = -30.0, 4.0  # log spacing between successive AR1 correlation scales

# Role of a filter state (docs/guide/theory.rst, 'Navigation filter'): what the filter's initial covariance and model
# swaps do with it.
ROLE_BIAS, ROLE_STATIONARY, ROLE_RAMP = 0, 1, 2


class FilterState(NamedTuple):
    """One state of a process' block over a filter step: x' = phi·x + q-noise, error += h·x
    (docs/guide/theory.rst, 'Navigation filter').
    ``bias_link``: the coefficient with which the state drives the bias state (a ramp: dt)."""

    phi: float
    q: float
    p0: float
    h: float
    role: int
    bias_link: float = 0.0


class StateBlock(NamedTuple):
    """A process' k coupled states over a filter step (k ≥ 2, e.g. an oscillator's rotation): x' = phi @ x + noise of
    covariance q, error += h @ x; ``p0`` the stationary covariance, ``role`` of every state (ROLE_STATIONARY:
    the filter starts it from ``p0``). Scalar states, which are most, stay :class:`FilterState` lists: the
    filter's arrays are the same and the stacking keeps its scalar path
    (docs/guide/theory.rst, 'Navigation filter')."""

    phi: tuple[tuple[float, ...], ...]
    q: tuple[tuple[float, ...], ...]
    p0: tuple[tuple[float, ...], ...]
    h: tuple[float, ...]
    role: int


class EquivalentPart(NamedTuple):
    """A process' share of the equivalent (N, K) pair (:mod:`imunoise.noise.equivalent_noise`): exact per-sample
    variances added to the white (``sigma2``) and random-walk (``gamma2``) parts, or ``matched`` (its WV joins
    the target the pair is matched to), with the route (``symbol``: N, K, N+K or -; ``text``)."""

    sigma2: float
    gamma2: float
    matched: bool
    symbol: str
    text: str


def dr_equivalent_rw(omega: float, horizon: float) -> float:
    """γ² (per sample) of the random walk with the same Haar WV as a drift ω at scale τ = ``horizon`` samples:
    ω²τ²/16 = γ²(τ² + 2)/(12τ) (docs/guide/theory.rst, 'Latent processes'), so γ² = 3ω²τ³/(4(τ² + 2)).

    Over the scales a static record covers, a ramp and a random walk are two readings of the same rising
    WV; a ramp state in the filter would extrapolate one fitted slope over the whole drive, while the
    random walk lets the filter track a bias that keeps wandering at the rate the data showed.
    """
    tau = float(horizon)
    return 3.0 * omega * omega * tau**3 / (4.0 * (tau * tau + 2.0))


def ar1_white_variance(phi: float, sigma2: float) -> float:
    """Per-sample variance of the white noise with the same zero-frequency density as AR1(φ, σ²): σ²/(1−φ)²."""
    return sigma2 / (1.0 - phi) ** 2


def fmt_seconds(t: float) -> str:
    """A duration for a route text: ms below 1 s."""
    return f"{t * 1e3:.3g} ms" if t < 1.0 else f"{t:.4g} s"


class Process:
    """One latent process; parameters per sample (docs/guide/theory.rst, 'Conventions'). Subclasses define the closed
    forms.

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
    continuous_units: ClassVar[dict[str, str]] = {}  # unit of each key of continuous(), in terms of "u"

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
        return type(self).from_values(values)

    @classmethod
    def from_values(cls, values: tuple[float, ...] | list[float] | np.ndarray) -> Process:
        """``cls(name=value, ...)`` in parameter order: the same checks and errors, without building the keyword
        dict when every value is there and finite (the model selection builds thousands of processes)."""
        names = cls.param_names
        vals = tuple(float(v) for _, v in zip(names, values))
        # (a process class with its own __init__ goes through it)
        if cls.__init__ is Process.__init__ and len(vals) == len(names) and all(math.isfinite(v) for v in vals):
            proc = object.__new__(cls)
            proc._validate(vals)
            proc._values = vals
            return proc
        return cls(**dict(zip(names, vals)))

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
        """Continuous-time equivalents (docs/guide/theory.rst, 'Latent processes' last column) in SI-style units of the
        data."""
        raise NotImplementedError

    # -- the estimator's unconstrained vector u (docs/guide/theory.rst, 'GMWM estimator')
    # ----------------------------------------------------
    code: ClassVar[int] = -1  # compiled kind code: position in PROCESS_TYPES
    singleton: ClassVar[bool] = True  # at most once per model (a sum of two is one of the same kind)
    nb_wv_u: ClassVar[Any] = None  # numba form in u (module comment above the forms)
    nb_wv_theta: ClassVar[Any] = None  # numba form in natural parameters

    @classmethod
    def u_bounds(cls, first: bool) -> tuple[list[float], list[float]]:
        """Box bounds of this process' entries of u; ``first``: no AR1 came before it (AR1 ordering)."""
        return [LOG_LO], [LOG_HI]

    @classmethod
    def theta_from_u(cls, u: np.ndarray, p: int, theta: np.ndarray, scale: float, chain: Any) -> Any:
        """Write θ[p:p+k] from u[p:p+k] (c = ``scale``); ``chain`` carries the AR1 ordering state, returned."""
        theta[p] = math.exp(u[p]) * scale
        return chain

    @classmethod
    def u_from_theta(cls, theta: np.ndarray, p: int, u: np.ndarray, scale: float, chain: Any) -> Any:
        """Inverse of :meth:`theta_from_u` (before clipping to the bounds)."""
        u[p] = math.log(max(theta[p] / scale, 1e-300))
        return chain

    # -- rate, filter and equivalent forms --------------------------------------------------------------------
    def at_rate(self, freq_from: float, freq_to: float) -> Process:
        """The same continuous-time process with parameters per sample at ``freq_to`` instead of ``freq_from``."""
        raise NotImplementedError

    def white_variance(self) -> float:
        """Per-sample variance this process adds to the filter's white part
        (docs/guide/theory.rst, 'Navigation filter')."""
        return 0.0

    def filter_block(self, steps: float, dt: float) -> tuple[float, list[FilterState] | StateBlock]:
        """(variance added to the bias state per filter step, own states) over a step of ``steps`` samples: scalar
        :class:`FilterState` s, or one :class:`StateBlock` of coupled states."""
        return 0.0, []

    keeps_filter_state: ClassVar[bool] = False  # the fit→filter door (imunoise.nav.filter_model) keeps it as its
    # own filter_block states instead of folding it into the white noise + random walk pair (equivalent_part)

    def scaled(self, white: float, bias: float) -> Process:
        """This process with its white variance × ``white`` or its bias driving variance × ``bias``."""
        return self

    def equivalent_part(self, name: str, freq: float, white_below: float, horizon_s: float | None, qn: str,
                        model_text: str) -> EquivalentPart:
        """This process' share of the (N, K) pair (:func:`imunoise.noise.equivalent_noise.equivalent_noise`)."""
        raise NotImplementedError

    def spectrum(self, f: np.ndarray, sin2: np.ndarray) -> np.ndarray | float:
        """Two-sided (pseudo-)spectral density at f cycles/sample (``sin2`` = sin²(πf)); 0 for none."""
        return 0.0

    def identification_jacobian(self, tau: np.ndarray) -> np.ndarray:
        """∂ν/∂θ in a parametrisation that never vanishes at 0 (the WVIC's rank count)."""
        return self.wv_jacobian(tau)

    em_form: ClassVar[str] = ""  # its place in the EM baseline's state-space form (imunoise.noise.em): "state" (a
    # first-order Kalman state with a closed-form M-step), "observation" (the observation noise), "drift" (a
    # deterministic regressor), "" (none: em_fit refuses the kind, naming it)
    reading: ClassVar[str] = "white"  # how a calibration reads it within a horizon: white, random_walk (as K),
    # gauss_markov (a value when T_c is inside the horizon), ramp (never a value)
    starts_fine: ClassVar[bool] = True  # the estimator's start reads the finest scale (else the coarsest)

    @classmethod
    def start_values(cls, frac: float, nu: np.ndarray, tau: np.ndarray) -> list[float]:
        """A starting θ for the estimator: the process carrying ``frac`` of the normalised empirical WV ``nu`` at
        the finest (``starts_fine``) or the coarsest scale of ``tau`` (docs/guide/theory.rst, 'GMWM estimator')."""
        raise NotImplementedError

    @classmethod
    def embedding(cls, frac: float, nu: np.ndarray, tau: np.ndarray) -> Process:
        """The process added to a fitted sub-model by the model selection: :meth:`start_values` kept off zero."""
        return cls.from_values([max(v, 1e-300) for v in cls.start_values(frac, nu, tau)])

    @classmethod
    def negligible(cls) -> Process:
        """The process at zero amplitude (the selection's exact embedding of a sub-model; 1e-300: the bound)."""
        return cls(**{name: 1e-300 for name in cls.param_names})

    def correlation_time(self, freq: float) -> float | None:
        """T_c [s] of a Gauss–Markov-like process at ``freq``, None for the others."""
        return None

    # -- algebra ----------------------------------------------------------------------------------
    # The sum type is set by imunoise.noise.model when it loads: the algebra needs Model, and Model needs the processes,
    # so the dependency points one way (model → processes). imunoise.noise.processes, where users import the processes
    # from, loads the model, so the algebra is there whatever was imported first.
    sum_type: ClassVar[Any] = None

    @staticmethod
    def _sum(components: list[Process]) -> Model:
        if Process.sum_type is None:
            raise ModelError("the model algebra needs imunoise.noise.model: import the processes from "
                             "imunoise.noise.processes (or imunoise), not from their family modules")
        return Process.sum_type(components)

    def __add__(self, other: Process | Model) -> Model:
        return self._sum([self]) + other

    def __radd__(self, other: object) -> Model:
        if other == 0:  # sum([...]) support
            return self._sum([self])
        return NotImplemented

    def __mul__(self, k: int) -> Model:
        if not isinstance(k, int) or isinstance(k, bool) or k < 1:
            raise ModelError(f"a process can be repeated a positive whole number of times, got {k!r}")
        return self._sum([self] * k)

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
