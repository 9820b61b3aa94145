"""Composite error models: sums of independent latent processes (docs/guide/theory.rst, 'Latent processes', paper Eq.
7).

``2 * AR1() + WN() + RW()`` builds a :class:`Model`. Its canonical form lists the AR1s first, ordered
by decreasing φ (slowest first, which removes label switching), then the others in the registry's order
(:data:`imunoise.noise.processes.ORDER`: WN, QN, RW, DR, MA1); parameters carry canonical names ``AR1_1.phi``,
``AR1_1.sigma2``, ..., ``WN.sigma2``, ``QN.q2``, ``RW.gamma2``, ``DR.omega``, ``MA1.theta``. All parameters are
per sample at the rate of the data they describe, which the model carries (``freq`` [Hz]: set by fits, model files
and :meth:`Model.with_freq`; None when unknown); every form needing a rate (continuous values, state space, the
filter) takes it from there, and the algebra keeps it (a sum of models at different rates is refused). Its forms
(WV, state space, white part, rate change) are sums or stacks of its processes' own
(:class:`imunoise.noise.process_base.Process`); nothing here branches on a kind except the AR1 ordering.
"""

from __future__ import annotations

import re
from collections import Counter
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.noise.model_rate import checked_freq, resolve_rate
from imunoise.noise.process_ar1 import AR1
from imunoise.noise.process_base import Process
from imunoise.noise.process_bias import DR, RW
from imunoise.noise.process_registry import ORDER, PROCESS_TYPES
from imunoise.noise.process_white import QN, WN
from imunoise.noise.state_space import StateSpace, stack_state_space

__all__ = ["Model", "StateSpace", "ORDER", "ModelLike", "as_model"]

_SINGLETONS = tuple(k for k, cls in PROCESS_TYPES.items() if cls.singleton)


class Model:
    """A sum of independent processes; see module docstring for the canonical form and names.

    Usually built with the algebra (``2 * AR1() + WN() + RW()``) or :meth:`parse`.

    Parameters
    ----------
    components : list or tuple of Process
        The processes, all with parameters or all without; WN, QN, RW and DR at most once each. AR1
        components are ordered by decreasing φ, the others canonically (:data:`ORDER`).
    freq : float, optional
        Rate [Hz] the per-sample parameters refer to; None when not known (module docstring).

    Raises
    ------
    ModelError
        For an empty list, a non-process, a repeated singleton, a mix of known and unknown processes, a bad rate.
    """

    def __init__(self, components: list[Process] | tuple[Process, ...], freq: float | None = None) -> None:
        self.freq: float | None = checked_freq(freq)
        comps = list(components)
        if not comps:
            raise ModelError("a model needs at least one process, e.g. WN() + RW()")
        for c in comps:
            if not isinstance(c, Process):
                raise ModelError(f"models are sums of {', '.join(ORDER)} processes, got {c!r}")
        counts = Counter(c.kind for c in comps)
        for kind in _SINGLETONS:
            if counts[kind] > 1:
                raise ModelError(
                    f"{kind} appears {counts[kind]} times; a sum of several {kind} is one {kind} "
                    "(not identifiable), use it once"
                )
        known = {c.known for c in comps}
        if len(known) > 1:
            raise ModelError("mixing processes with and without parameters; give all parameters or none")
        ar1s = [c for c in comps if c.kind == "AR1"]
        if ar1s and ar1s[0].known:
            ar1s.sort(key=lambda c: -c.values[0])
        rest = sorted((c for c in comps if c.kind != "AR1"), key=lambda c: ORDER.index(c.kind))
        self.components: tuple[Process, ...] = tuple(ar1s + rest)

    # -- construction -------------------------------------------------------------------------------
    @classmethod
    def parse(cls, text: str) -> Model:
        """Read ``"2*AR1 + WN + RW"`` (also ``AR1()``, ``2 AR1``, ``2xAR1``); inverse of ``str()``.

        Parameters
        ----------
        text : str
            Terms joined by ``+``, each a process name with an optional repeat count.

        Returns
        -------
        Model
            The structure, parameters unknown.

        Raises
        ------
        ModelError
            For an empty string or a term that is not a process.
        """
        if not isinstance(text, str) or not text.strip():
            raise ModelError(f"empty model string; write e.g. '2*AR1+WN+RW' (processes: {', '.join(ORDER)})")
        comps: list[Process] = []
        for term in text.split("+"):
            term = term.strip().replace("()", "")
            match = re.fullmatch(r"(?:(\d+)\s*[*x×]?\s*)?([A-Za-z][A-Za-z0-9]*)", term)
            if not match or match.group(2).upper() not in PROCESS_TYPES:
                raise ModelError(
                    f"cannot read model term {term!r} in {text!r}; write terms like '2*AR1', 'WN' "
                    f"joined by '+' (processes: {', '.join(ORDER)})"
                )
            k = int(match.group(1) or 1)
            if k < 1:
                raise ModelError(f"repeat count must be ≥ 1 in {term!r}")
            comps.extend(PROCESS_TYPES[match.group(2).upper()]() for _ in range(k))
        return cls(comps)

    def __add__(self, other: Process | Model) -> Model:
        if isinstance(other, Process):
            return Model(list(self.components) + [other], self.freq)
        if isinstance(other, Model):
            if self.freq is not None and other.freq is not None and self.freq != other.freq:
                raise ModelError(
                    f"cannot add a model at {self.freq:g} Hz to one at {other.freq:g} Hz (parameters are per sample "
                    f"at their rate); convert one first, e.g. b.at_rate({other.freq:g}, {self.freq:g})"
                )
            freq = self.freq if self.freq is not None else other.freq
            return Model(list(self.components) + list(other.components), freq)
        return NotImplemented

    def __radd__(self, other: object) -> Model:
        if other == 0:
            return self
        return NotImplemented

    def __mul__(self, k: int) -> Model:
        if not isinstance(k, int) or isinstance(k, bool) or k < 1:
            raise ModelError(f"a model can be repeated a positive whole number of times, got {k!r}")
        return Model(list(self.components) * k, self.freq)

    __rmul__ = __mul__

    # -- structure -------------------------------------------------------------------------------------
    @property
    def counts(self) -> Counter:
        return Counter(c.kind for c in self.components)

    @property
    def structure(self) -> str:
        return str(self)

    def __str__(self) -> str:
        counts = self.counts
        parts = []
        for kind in ORDER:
            k = counts.get(kind, 0)
            if k:
                parts.append(kind if k == 1 else f"{k}*{kind}")
        return " + ".join(parts)

    def __repr__(self) -> str:
        if self.known:
            return " + ".join(repr(c) for c in self.components)
        return f"Model({str(self)!r})"

    def __eq__(self, other: object) -> bool:  # a model without a rate matches any rate (fit starts, caches)
        return (isinstance(other, Model) and self.components == other.components
                and (self.freq is None or other.freq is None or self.freq == other.freq))

    def __hash__(self) -> int:
        return hash(self.components)

    # -- sample rate ---------------------------------------------------------------------------------
    def with_freq(self, freq: float | None) -> Model:
        """This model stating that its parameters are per sample at ``freq`` [Hz] (no conversion: use
        :meth:`at_rate` to express the same continuous-time model at another rate); None forgets the rate."""
        return Model(self.components, freq)

    def sample_rate(self, freq: float | None = None, what: str = "this") -> float:
        """The rate [Hz] the parameters refer to: the model's own, else ``freq``; ModelError when neither is
        known or they differ (:func:`imunoise.noise.model_rate.resolve_rate`, whose message names the fix)."""
        return resolve_rate(self, self.freq, freq, what)

    def nests(self, other: Model) -> bool:
        """True when every process of ``other`` is also in this model (this model ⊇ other)."""
        mine, theirs = self.counts, other.counts
        return all(mine.get(k, 0) >= v for k, v in theirs.items())

    def unknown(self) -> Model:
        """The same structure with parameters to be estimated."""
        return Model([c.unknown() for c in self.components], self.freq)

    @property
    def known(self) -> bool:
        return all(c.known for c in self.components)

    @property
    def n_ar1(self) -> int:
        return self.counts.get("AR1", 0)

    def has(self, kind: str) -> bool:
        return self.counts.get(kind, 0) > 0

    # -- parameters --------------------------------------------------------------------------------
    def component_names(self) -> list[str]:
        """Canonical component names: AR1_1, AR1_2, ..., WN, QN, RW, DR."""
        names, i = [], 0
        for c in self.components:
            if c.kind == "AR1":
                i += 1
                names.append(f"AR1_{i}")
            else:
                names.append(c.kind)
        return names

    @property
    def param_names(self) -> list[str]:
        return [
            f"{cname}.{p}" for cname, c in zip(self.component_names(), self.components) for p in c.param_names
        ]

    @property
    def n_params(self) -> int:
        return sum(len(c.param_names) for c in self.components)

    @property
    def vector(self) -> np.ndarray:
        """Natural parameter vector in canonical order (same order as ``param_names``)."""
        return np.array([v for c in self.components for v in c.values], dtype=float)

    @property
    def params(self) -> dict[str, float]:
        return dict(zip(self.param_names, self.vector.tolist()))

    def with_vector(self, theta: np.ndarray | list[float]) -> Model:
        """The same structure with natural parameters θ (canonical order); AR1s are re-sorted by φ."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape != (self.n_params,):
            raise ModelError(f"{self} has {self.n_params} parameters, got a vector of shape {theta.shape}")
        comps, i = [], 0
        for c in self.components:
            k = len(c.param_names)
            comps.append(c.with_values(theta[i : i + k]))
            i += k
        return Model(comps, self.freq)

    def with_params(self, params: dict[str, float]) -> Model:
        """The same structure with parameters given by canonical name (all must be present)."""
        missing = [n for n in self.param_names if n not in params]
        if missing:
            raise ModelError(f"missing parameters {missing} for model {self}; expected {self.param_names}")
        extra = sorted(set(params) - set(self.param_names))
        if extra:
            raise ModelError(f"unknown parameters {extra} for model {self}; expected {self.param_names}")
        return self.with_vector(np.array([params[n] for n in self.param_names], dtype=float))

    # -- wavelet variance ------------------------------------------------------------------------------
    def wv(self, scales: np.ndarray) -> np.ndarray:
        """Theoretical Haar WV ν²(τ) at scales τ (samples): the sum of the processes' WVs
        (docs/guide/theory.rst, 'Latent processes').

        Parameters
        ----------
        scales : numpy.ndarray
            τ_j [samples].

        Returns
        -------
        numpy.ndarray
            ν²(τ_j) [u²], one per scale.
        """
        tau = np.asarray(scales, dtype=float)
        return np.sum([c.wv(tau) for c in self.components], axis=0)

    def component_wv(self, scales: np.ndarray) -> dict[str, np.ndarray]:
        """WV of each process by canonical component name (for per-process plot curves)."""
        tau = np.asarray(scales, dtype=float)
        return {name: c.wv(tau) for name, c in zip(self.component_names(), self.components)}

    def wv_jacobian(self, scales: np.ndarray) -> np.ndarray:
        """∂ν²/∂θ for the natural parameters θ in canonical order, shape (len(scales), n_params)."""
        tau = np.asarray(scales, dtype=float)
        return np.hstack([c.wv_jacobian(tau) for c in self.components])

    # -- simulation --------------------------------------------------------------------------------------
    def simulate(self, n: int, seed: int | np.random.Generator | None = None) -> np.ndarray:
        """A sample path of length n (per-sample parameters, stationary AR1 starts).

        Parameters
        ----------
        n : int
            Number of samples (≥ 1).
        seed : int or numpy.random.Generator, optional
            Seed or generator of the random path.

        Returns
        -------
        numpy.ndarray
            The path [u], shape (n,).
        """
        if not isinstance(n, (int, np.integer)) or n < 1:
            raise ModelError(f"simulate needs a positive number of samples, got {n!r}")
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        return np.sum([c.simulate(int(n), rng) for c in self.components], axis=0)

    # -- continuous-time and filter forms --------------------------------------------------------------
    def continuous(self, freq: float | None = None) -> dict[str, float]:
        """Continuous-time equivalents with canonical keys (docs/guide/theory.rst, 'Latent processes'): noise density,
        K, T_c, ...

        Parameters
        ----------
        freq : float, optional
            Sample rate the per-sample parameters refer to [Hz]; default (and only accepted value when it has
            one) the model's own (:meth:`sample_rate`).

        Returns
        -------
        dict
            Value per key, e.g. ``"WN.noise_density"``, ``"RW.random_walk"``, ``"AR1_1.tau_c"``.
        """
        if freq is not None and not freq > 0:
            raise ModelError(f"sampling frequency must be > 0 Hz, got {freq}")
        freq = self.sample_rate(freq, "continuous()")
        out: dict[str, float] = {}
        for name, c in zip(self.component_names(), self.components):
            out.update(c.continuous(freq, name))
        return out

    def white_variance(self) -> float:
        """Per-sample variance of the white part: σ²_WN + 2Q² (QN x_t = u_t − u_{t−1} treated as white)."""
        total = 0.0
        for c in self.components:
            w = c.white_variance()
            if w:
                total += w
        return total

    def scaled(self, white: float = 1.0, bias: float = 1.0) -> Model:
        """This model with the white-noise variance σ²_WN × ``white`` and the driving variance of its bias
        processes (RW γ², AR1 σ²; φ and so T_c kept) × ``bias``; QN and DR unchanged. The one scaling of the
        motion law's moving regime (:func:`imunoise.sim.motion.scaled_models`) and of the adaptive baseline
        (:func:`imunoise.nav.adaptive.scale_bias_noise`)."""
        out = [c.scaled(white, bias) for c in self.components]
        return Model(out, self.freq)

    def state_space(self, dt: float, freq: float | None = None) -> StateSpace:
        """Discrete (Φ, Q, H) blocks over a filter step dt for parameters per sample at ``freq``
        (docs/guide/theory.rst, 'Navigation filter').

        AR1 over dt: Φ = φ^{dt·f}, Q = σ²_GM(1 − Φ²). RW adds γ²·dt·f to the bias state. DR is a constant
        ramp state r (unit/s) with bias_{k+1} = bias_k + r·dt. ``freq`` defaults to the model's own rate
        (:meth:`sample_rate`), else 1/dt.

        Parameters
        ----------
        dt : float
            Filter step [s].
        freq : float, optional
            Sample rate the parameters refer to [Hz] (default the model's own, else 1/dt; a different one is
            refused).

        Returns
        -------
        StateSpace
        """
        if self.freq is not None:
            freq = self.sample_rate(freq, "state_space()")
        return stack_state_space(self, dt, freq)

    def at_rate(self, freq_from: float, freq_to: float) -> Model:
        """The same continuous-time model with parameters per sample at ``freq_to`` instead of ``freq_from``
        (N, K, R, Q_IEEE, T_c and σ_GM kept; docs/guide/theory.rst, 'Latent processes' last column). Unchanged when the
        rates are equal. ``freq_from`` must be the model's own rate when it has one; the result carries ``freq_to``."""
        if not (freq_from > 0 and freq_to > 0):
            raise ModelError(f"sample rates must be > 0 Hz, got {freq_from} and {freq_to}")
        self.sample_rate(freq_from, "at_rate()")
        if freq_from == freq_to:
            return self if self.freq == freq_to else self.with_freq(freq_to)
        return Model([c.at_rate(float(freq_from), float(freq_to)) for c in self.components], float(freq_to))

    # -- serialisation -----------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"model": str(self)}
        if self.known:
            d["params"] = self.params
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Model:
        """Inverse of :meth:`to_dict`; also reads fit JSON (keys ``model`` and ``params``, and the rate from
        ``freq_hz`` or ``rate_hz`` when present)."""
        if "model" not in d:
            raise ModelError("model JSON needs a 'model' key, e.g. {'model': '2*AR1 + WN', 'params': {...}}")
        rate = d.get("freq_hz", d.get("rate_hz"))
        model = cls.parse(d["model"]).with_freq(None if rate is None else float(rate))
        params = d.get("params")
        return model.with_params(params) if params else model


Process.sum_type = Model  # the processes' algebra (``WN() + RW()``) builds this type

ModelLike = Process | Model | str
"""What every estimator accepts as a model: ``WN()``, ``2 * AR1() + WN()`` or ``"2*AR1+WN"``."""


def as_model(model: ModelLike) -> Model:
    """The :class:`Model` meant by ``model``: a single process, a Model, or a model string
    (docs/guide/theory.rst, 'Latent processes').

    Every estimator (``gmwm``, ``refit``, ``em_fit``, ``select_model``'s ``complete=``) takes its model
    through this function, so ``WN()``, ``WN() + RW()``, ``Model([WN()])`` and ``"WN+RW"`` are all the
    same thing everywhere. A process class (``WN`` without parentheses) is taken as ``WN()``.

    Parameters
    ----------
    model
        A :class:`~imunoise.noise.processes.Process` (with or without parameters), a :class:`Model`, or a
        string read by :meth:`Model.parse`.

    Returns
    -------
    Model
        ``model`` itself when it is a Model, otherwise the equivalent one-or-more-process Model.

    Raises
    ------
    ModelError
        For anything else, with a hint when the arguments look swapped (data where the model goes).
    """
    if isinstance(model, Model):
        return model
    if isinstance(model, Process):
        return Model([model])
    if isinstance(model, str):
        return Model.parse(model)
    if isinstance(model, type) and issubclass(model, Process) and model is not Process:
        return Model([model()])
    hint = ""
    if isinstance(model, (np.ndarray, list, tuple)) or hasattr(model, "__array__"):
        # the old em_fit(data, model=...) order, or gmwm(data, model): say which order is meant
        hint = "; this looks like data: estimators take (model, data), e.g. gmwm(WN() + RW(), x, freq=100.0)"
    raise ModelError(
        f"expected a model (a process such as WN(), a sum such as 2 * AR1() + WN(), or a string such as "
        f"'2*AR1+WN'), got {type(model).__name__}{hint}"
    )


def default_complete() -> Model:
    """The paper's complete model, Eq. (7): 4×AR1 + DR + WN + QN + RW."""
    return 4 * AR1() + DR() + WN() + QN() + RW()
