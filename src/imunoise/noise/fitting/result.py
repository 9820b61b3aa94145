"""The result of a fit (docs/guide/theory.rst, 'GMWM estimator'): :class:`GMWMFit`, its confidence intervals, summary
and JSON form.

Every estimator (GMWM, refit, model selection, the AV and EM baselines) builds its result with the one
factory :meth:`GMWMFit.from_problem`, so that WV, Ω, rate and GOF (paper Eq. 8) are always taken from
the same :class:`~imunoise.noise.fitting.problem.GMWMProblem`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import norm

from imunoise._version import __version__
from imunoise.errors import ModelError
from imunoise.noise.fitting.identifiability import collapsed_components
from imunoise.noise.fitting.params import kind_codes, theta_to_u, u_to_theta
from imunoise.noise.fitting.problem import GMWMProblem
from imunoise.noise.fitting.summary_text import (
    CONTINUOUS_UNITS,
    PARAM_UNITS,
    band_departures,
    ci_text,
    departures_text,
    unit_text,
)
from imunoise.noise.model import Model
from imunoise.noise.wv import WaveletVariance

__all__ = [
    "GMWMFit",
    "PARAM_UNITS",
    "CONTINUOUS_UNITS",
    "unit_text",
    "band_departures",
    "departures_text",
]


def _exp(v: float) -> float:
    """exp that saturates to inf: a component collapsed to ~0 has a log-scale CI wide enough to overflow."""
    return math.exp(v) if v < 709.0 else math.inf


@dataclass
class GMWMFit:
    """Result of :func:`imunoise.noise.estimator.gmwm` and the other estimators
    (docs/guide/theory.rst, 'GMWM estimator').

    ``objective`` is the paper's GOF (Eq. 8). Build one with :meth:`from_problem`.

    Attributes
    ----------
    model : Model
        The fitted model (known parameters, per sample; ``params`` gives them by name).
    objective : float
        GOF (ν̂ − ν(θ̂))ᵀ Ω (ν̂ − ν(θ̂)) at the estimate (paper Eq. 8).
    wv : WaveletVariance
        The empirical WV the model was fitted to.
    weights : str
        How Ω was formed: ``"efficient"``, ``"diagonal"``, ``"fast"``, ``"identity"`` or ``"custom"``.
    omega_sqrt : numpy.ndarray
        W with WᵀW = Ω, shape (J, J).
    converged : bool
        Whether the solver met its tolerance.
    elapsed_s : float
        Wall-clock time of the fit [s].
    freq : float
        Sample rate [Hz].
    unit : str
        Unit of the data (``u`` in the parameter units).
    iterations : int
        Solver iterations.
    n_starts : int
        Starting points tried.
    param_cov_u : numpy.ndarray or None
        Covariance of the internal (unconstrained) parameters u, for the confidence intervals.
    method : str
        The estimator (``"gmwm"``, ``"em"``, ``"av"``, …).
    extra : dict
        Estimator-specific details.
    """

    model: Model
    objective: float
    wv: WaveletVariance
    weights: str
    omega_sqrt: np.ndarray
    converged: bool
    elapsed_s: float
    freq: float = 1.0
    unit: str = "u"
    iterations: int = 0
    n_starts: int = 0
    param_cov_u: np.ndarray | None = None  # covariance of the internal parameters u
    method: str = "gmwm"
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # the fitted model carries the rate its parameters are per sample at (Model.freq); one at another rate
        # is refused with the fix (imunoise.noise.model_rate.resolve_rate)
        self.model = self.model.with_freq(self.model.sample_rate(self.freq, "a fit"))

    @classmethod
    def from_problem(
        cls,
        problem: GMWMProblem,
        model: Model,
        *,
        objective: float | None = None,
        converged: bool = True,
        method: str = "gmwm",
        unit: str = "u",
        iterations: int = 0,
        n_starts: int = 0,
        elapsed_s: float = 0.0,
        param_cov_u: np.ndarray | None = None,
        extra: dict[str, Any] | None = None,
    ) -> GMWMFit:
        """The fit of ``model`` on ``problem``: the one place a :class:`GMWMFit` is assembled
        (docs/guide/theory.rst, 'GMWM estimator').

        Parameters
        ----------
        problem
            The problem the model was estimated on; its WV, Ω (``W``), weight name and rate are stored.
        model
            The estimated model (parameters per sample at ``problem.wv.freq``).
        objective
            The GOF (paper Eq. 8); default ``problem.objective(model)``. Model selection passes its own
            compiled evaluation so that all candidates are compared on numbers computed the same way.
        converged
            Whether the estimator reached its stopping rule.
        method
            ``"gmwm"``, ``"av"`` (Allan baseline, docs/guide/theory.rst, 'Baselines') or ``"em"`` (EM baseline).
        unit
            Data unit named in summaries and JSON (``"u"``: unspecified).
        iterations, n_starts
            Solver iterations and starting points tried.
        elapsed_s
            Wall time of the estimate [s].
        param_cov_u
            Covariance of the unconstrained parameters (:func:`imunoise.noise.fitting.problem.param_cov`).
        extra
            Method-specific results (WVIC, Allan reading, EM log-likelihood, data span, ...).

        Returns
        -------
        GMWMFit
        """
        return cls(
            model=model,
            objective=problem.objective(model) if objective is None else objective,
            wv=problem.wv,
            weights=problem.weights,
            omega_sqrt=problem.W,
            converged=bool(converged),
            elapsed_s=elapsed_s,
            freq=float(problem.wv.freq),
            unit=unit,
            iterations=iterations,
            n_starts=n_starts,
            param_cov_u=param_cov_u,
            method=method,
            extra={} if extra is None else extra,
        )

    # -- basic views ------------------------------------------------------------------------------
    @property
    def params(self) -> dict[str, float]:
        return self.model.params

    @property
    def theoretical_wv(self) -> np.ndarray:
        return self.model.wv(self.wv.scales)

    @property
    def n_params(self) -> int:
        return self.model.n_params

    @property
    def omega(self) -> np.ndarray:
        return self.omega_sqrt.T @ self.omega_sqrt

    def objective_at(self, params: dict[str, float] | Model) -> float:
        """The same objective (same WV, same Ω; paper Eq. 6/8) at other parameters.

        Parameters
        ----------
        params
            Parameters with canonical names (e.g. ``{"WN.sigma2": 1e-4}``) or a model of the same structure.

        Returns
        -------
        float
            (ν̂ − ν(θ))ᵀΩ(ν̂ − ν(θ)).
        """
        model = params if isinstance(params, Model) else self.model.unknown().with_params(params)
        r = self.omega_sqrt @ (self.wv.variance - model.wv(self.wv.scales))
        return float(r @ r)

    def continuous(self) -> dict[str, float]:
        """Continuous-time equivalents, docs/guide/theory.rst, 'Conventions'–2 (units in :meth:`continuous_units`)."""
        return self.model.continuous(self.freq)

    def param_units(self) -> dict[str, str]:
        return {f"{name}.{n}": unit_text(u.replace("^2", "²"), self.unit)
                for name, c in zip(self.model.component_names(), self.model.components)
                for n, u in zip(c.param_names, c.param_units)}

    def continuous_units(self) -> dict[str, str]:
        return {f"{name}.{k}": unit_text(u, self.unit)
                for name, c in zip(self.model.component_names(), self.model.components)
                for k, u in c.continuous_units.items()}

    # -- confidence intervals (delta method in the unconstrained parametrisation) -------------------------
    def _u(self) -> np.ndarray:
        return theta_to_u(self.model.vector, kind_codes(self.model), 1.0)

    def _link_values(self, u: np.ndarray) -> dict[str, float]:
        model = self.model.with_vector(u_to_theta(u, kind_codes(self.model), 1.0))
        out = {}
        for name, value in model.params.items():
            out[name] = (
                math.log(-math.log(value)) if name.endswith(".phi") else math.log(max(abs(value), 1e-300))
            )
        for name, value in model.continuous(self.freq).items():
            out[name] = math.log(max(abs(value), 1e-300))
        return out

    def confidence_intervals(self, level: float = 0.95) -> dict[str, tuple[float, float]]:
        """Asymptotic CIs of every per-sample and continuous quantity (NaN where not available).

        Cov(û) is the GMM sandwich (GᵀΩG)⁻¹GᵀΩVΩG(GᵀΩG)⁻¹ with V the WV covariance; each quantity's CI
        is taken on a log scale (log(−ln φ) for φ) and mapped back, so it stays in its valid range.

        Parameters
        ----------
        level
            Coverage of the intervals.

        Returns
        -------
        dict
            ``{name: (low, high)}`` for every per-sample parameter and continuous quantity.
        """
        names = self.model.param_names + list(self.continuous())
        if self.param_cov_u is None or np.any(np.isnan(self.param_cov_u)):
            return {n: (math.nan, math.nan) for n in names}
        cov = self.param_cov_u
        free = np.isinf(np.diag(cov))  # not identified (see imunoise.noise.fitting.problem.param_cov)
        cov_id = np.where(np.isinf(cov), 0.0, cov)
        z = float(norm.ppf(0.5 + level / 2))
        u0 = self._u()
        base = self._link_values(u0)
        grads = {n: np.zeros(len(u0)) for n in base}
        for i in range(len(u0)):
            h = 1e-6 * max(1.0, abs(u0[i]))
            up, dn = u0.copy(), u0.copy()
            up[i] += h
            dn[i] -= h
            vu, vd = self._link_values(up), self._link_values(dn)
            for n in base:
                grads[n][i] = (vu[n] - vd[n]) / (2 * h)
        values = {**self.params, **self.continuous()}
        out = {}
        for n in names:
            g = grads[n]
            if np.any(np.abs(g[free]) > 1e-9):
                out[n] = (math.nan, math.nan)
                continue
            se = math.sqrt(max(float(g @ cov_id @ g), 0.0))
            lo, hi = base[n] - z * se, base[n] + z * se
            if n.endswith(".phi"):
                out[n] = (math.exp(-_exp(hi)), math.exp(-_exp(lo)))
            else:
                sign = -1.0 if values[n] < 0 else 1.0
                a, b = sign * _exp(lo), sign * _exp(hi)
                out[n] = (min(a, b), max(a, b))
        return collapsed_components(out, self.model)

    # -- reporting --------------------------------------------------------------------------------------
    def summary(self, level: float = 0.95) -> str:
        """Table of every parameter, per sample and continuous, with units and CIs.

        Parameters
        ----------
        level
            Coverage of the confidence intervals.

        Returns
        -------
        str
            Multi-line text (header with GOF, convergence, band departures; then the parameter tables).
        """
        ci = self.confidence_intervals(level)
        has_ci = self.param_cov_u is not None and not np.any(np.isnan(self.param_cov_u))
        pct = f"{100 * level:.0f}% CI"
        head = f"per sample (discrete, at {self.freq:g} Hz)"
        lines = [
            f"{self.method.upper()} fit of {self.model} at {self.freq:g} Hz "
            f"(data unit {self.unit}; weights {self.weights})",
            f"  objective (GOF, Eq. 8) = {self.objective:.6g}   converged = {self.converged}   "
            f"time = {1e3 * self.elapsed_s:.1f} ms   levels = {len(self.wv.variance)}",
        ]
        bad = band_departures(self.wv, self.theoretical_wv)
        if bad:
            lines.append(
                f"  fit outside the {100 * (1 - self.wv.alpha):.0f}% WV band at τ = {departures_text(bad)}"
            )
        lines += [
            "",
            f"  {head:<40}{'value':>14}  {pct:^29}  unit",
        ]
        units = self.param_units()
        for n, v in self.params.items():
            lines.append(f"  {n:<40}{v:>14.6g}  {ci_text(ci.get(n), has_ci)}  {units[n]}")
        lines += ["", f"  {'continuous-time equivalents':<40}{'value':>14}  {pct:^29}  unit"]
        cunits = self.continuous_units()
        for n, v in self.continuous().items():
            lines.append(f"  {n:<40}{v:>14.6g}  {ci_text(ci.get(n), has_ci)}  {cunits[n]}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    # -- serialisation ----------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: model, parameters (discrete + continuous, units), rate, data span, WV, Ω.

        Returns
        -------
        dict
            ``kind = "imunoise.fit"``; read back by :meth:`from_dict`.
        """
        return {
            "kind": "imunoise.fit",
            "imunoise_version": __version__,
            "method": self.method,
            "model": str(self.model),
            "params": self.params,
            "param_units": self.param_units(),
            "continuous": self.continuous(),
            "continuous_units": self.continuous_units(),
            "freq_hz": self.freq,
            "unit": self.unit,
            "objective": self.objective,
            "weights": self.weights,
            "converged": self.converged,
            "elapsed_s": self.elapsed_s,
            "iterations": self.iterations,
            "n_starts": self.n_starts,
            "data_span": dict(self.extra.get("data_span", {})),
            "wv": self.wv.to_dict(),
            "omega_sqrt": self.omega_sqrt.tolist(),
            "param_cov_u": None if self.param_cov_u is None else self.param_cov_u.tolist(),
            "extra": self.extra,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> GMWMFit:
        """The fit written by :meth:`to_dict`.

        Parameters
        ----------
        d
            A dict with ``kind = "imunoise.fit"`` (else ``ModelError``).

        Returns
        -------
        GMWMFit
        """
        if d.get("kind") != "imunoise.fit":
            raise ModelError("not an imunoise fit JSON (missing kind 'imunoise.fit')")
        model = Model.parse(d["model"]).with_params(d["params"])
        cov = d.get("param_cov_u")
        return cls(
            model=model,
            objective=float(d["objective"]),
            wv=WaveletVariance.from_dict(d["wv"]),
            weights=d["weights"],
            omega_sqrt=np.array(d["omega_sqrt"], dtype=float),
            converged=bool(d["converged"]),
            elapsed_s=float(d["elapsed_s"]),
            freq=float(d["freq_hz"]),
            unit=d.get("unit", "u"),
            iterations=int(d.get("iterations", 0)),
            n_starts=int(d.get("n_starts", 0)),
            param_cov_u=None if cov is None else np.array(cov, dtype=float),
            method=d.get("method", "gmwm"),
            extra=dict(d.get("extra", {})),
        )

    def save(self, path: str) -> None:
        """Write :meth:`to_dict` as JSON (atomically: no half-written file on a crash).

        Parameters
        ----------
        path
            Output file.
        """
        from imunoise.io.atomic import atomic_write_text

        atomic_write_text(path, json.dumps(self.to_dict(), indent=1))

    @classmethod
    def load(cls, path: str) -> GMWMFit:
        """Read a fit saved by :meth:`save` (or the ``model.json`` of ``imunoise fit``/``select``).

        Parameters
        ----------
        path
            A JSON file of :meth:`to_dict`.

        Returns
        -------
        GMWMFit
            Any other file (YAML, a multi-axis model of ``ImuModel.load``, binary, truncated) raises one
            :class:`~imunoise.errors.ModelError` naming ``path`` and what was expected.
        """
        from imunoise.errors import ImunoiseError
        from imunoise.io.files import read_text

        expected = "the model.json written by GMWMFit.save or `imunoise fit`/`imunoise select`"
        text = read_text(path, "fit file", ModelError, expected=expected)
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ModelError(
                f"fit file {path} is not JSON ({exc.msg} at line {exc.lineno}); GMWMFit.load reads {expected}"
            ) from exc
        if not isinstance(d, dict):
            raise ModelError(f"fit file {path} holds a JSON {type(d).__name__}, not a fit; give {expected}")
        try:
            return cls.from_dict(d)
        except ImunoiseError as exc:
            raise ModelError(f"fit file {path}: {exc}; give {expected}") from exc
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(
                f"fit file {path}: not a complete imunoise fit (bad or missing {exc}); give {expected}"
            ) from exc

