"""EM baseline: constrained expectation–maximisation on the state-space form (Stebler et al. 2011;
docs/guide/theory.rst, 'Baselines').

Stebler, Guerrier, Skaloud & Victoria-Feser (2011), "Constrained expectation-maximization algorithm for
stochastic inertial error modeling: study of feasibility", Meas. Sci. Technol. 22, 085204.

Model of one sensor axis (per sample, data de-meaned): y_t = Σ_i x_{i,t} + b_t + ω(t − t̄) + v_t with
AR1 states x_{i,t} = φ_i x_{i,t−1} + e_{i,t} (Var e = σ²_i), an RW state b_t = b_{t−1} + η_t (Var η = γ²),
WN v_t (Var σ²_WN) as the observation noise and an optional deterministic drift ω. QN is not a
state-space process here (it is not Markov of order one in this form) and is rejected.

E-step (:mod:`imunoise.noise.em_kalman`): Kalman filter and Rauch–Tung–Striebel smoother with the lag-one covariance
Cov(x_{t+1}, x_t | Y) = P_{t+1|n} J_tᵀ (numba, scalar observation). The model is time invariant, so the
filter and smoother covariances reach a steady state; once the relative change of the predicted
covariance is below 1e-12 it is frozen (and the backward one likewise inside the frozen stretch), which
makes an iteration O(n·k²) and keeps memory O(n·k) for long series.
M-step (closed form, conditional on the first state): φ_i = S10/S00, σ²_i = (S11 − φ_i S10)/(n − 1),
γ² = (S11 − 2S10 + S00)/(n − 1), σ²_WN = mean E[(y_t − Hx_t − ω(t − t̄))²], ω = Σ(t − t̄)(y_t − Hx̂_t)/Σ(t − t̄)².
Constraints by projection: φ ∈ [1e-6, 1 − 1e-10], variances ≥ 1e-14·Var(y) (a structural zero would
freeze EM there), AR1s re-sorted by φ. The initial AR1 state has its stationary variance, the RW state
a diffuse variance Var(y)·100.
Stopping: relative change of the log-likelihood below ``tol`` (default 1e-8) or ``max_iter``. A
non-finite or decreasing likelihood is flagged (``extra["diverged"]``, ``extra["decreases"]``) and the
best iterate is kept. The default start is the AV result (:func:`imunoise.noise.allan.allan_fit`), as in the
paper; ``init=`` accepts any fit or model.
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Any

import numpy as np

from imunoise.errors import DataError, FitError, ModelError
from imunoise.noise.em_kalman import kalman_estep, kalman_loglik, state_form
from imunoise.noise.fitting.arguments import check_unit
from imunoise.noise.fitting.problem import prepare
from imunoise.noise.fitting.result import GMWMFit
from imunoise.noise.model import Model, ModelLike, as_model
from imunoise.noise.processes import AR1, DR, PROCESS_TYPES, RW, WN
from imunoise.units import required_freq

__all__ = ["em_fit", "kalman_loglik", "check_em_kinds"]

_PHI_LO, _PHI_HI = 1e-6, 1.0 - 1e-10

def _start_model(structure: Model, init: Model | None, var_y: float) -> Model:
    """Parameters for ``structure`` from ``init`` (matching processes), defaults for the rest."""
    comps = []
    init_ar = [c for c in init.components if c.kind == "AR1"] if init is not None else []
    n_ar = structure.n_ar1
    default_phis = np.exp(-1.0 / np.geomspace(1e4, 10.0, max(n_ar, 1)))
    for i in range(n_ar):
        if i < len(init_ar):
            phi, s2 = init_ar[i].values
        else:
            phi = float(default_phis[i])
            s2 = 0.01 * var_y * (1.0 - phi * phi)
        comps.append(AR1(phi=float(np.clip(phi, _PHI_LO, _PHI_HI)), sigma2=max(s2, 1e-14 * var_y)))
    for kind, proc, default in (
        ("WN", WN, 0.5 * var_y),
        ("RW", RW, 1e-8 * var_y),
        ("DR", DR, 0.0),
    ):
        if structure.has(kind):
            val = None
            if init is not None and init.has(kind):
                val = next(c.values[0] for c in init.components if c.kind == kind)
            v = default if val is None else val
            if kind != "DR":
                v = max(v, 1e-14 * var_y)
            comps.append(proc(**{proc.param_names[0]: v}))
    return Model(comps)


def check_em_kinds(structure: Model) -> None:
    """Refuse, in one line naming it, a kind the EM's state-space form has no place for (its class' ``em_form``
    is empty: QN, MA1), instead of fitting the model without it."""
    bad = sorted({c.kind for c in structure.components if not type(c).em_form})
    if bad:
        handled = [k for k, cls in PROCESS_TYPES.items() if cls.em_form]
        raise ModelError(f"em_fit: {', '.join(bad)} has no place in the EM's state-space form (it handles "
                         f"{', '.join(handled)}); remove {', '.join(bad)} from the model or fit it with gmwm()")


def _looks_like_data(x: Any) -> bool:
    # what the old em_fit(data, ...) order put first: an array or a list of segments, never a model
    return isinstance(x, (np.ndarray, list, tuple)) or (hasattr(x, "__array__") and not isinstance(x, str))


def _em_arguments(model: Any, data: Any, legacy: dict[str, Any]) -> tuple[Any, Any]:
    """(model, data) of an em_fit call; the earlier order ``em_fit(data, model=...)`` still works for one
    release with a DeprecationWarning (all estimators now take ``(model, data)`` like :func:`gmwm`)."""
    extra = sorted(set(legacy) - {"model", "data"})
    if extra:
        raise TypeError(f"em_fit() got an unexpected keyword argument {extra[0]!r}")
    if "data" in legacy:
        if data is not None:
            raise TypeError("em_fit() got the data twice: as the second argument and as data=")
        data = legacy["data"]
    old_order = data is None and _looks_like_data(model)
    if old_order:
        data, model = model, legacy.get("model")
        warnings.warn(
            "em_fit(data, model=...) is deprecated: estimators take (model, data) like gmwm; call "
            "em_fit(model, data, freq=...) (model None: the structure of init=). The old order stops "
            "working in the next release.",
            DeprecationWarning,
            stacklevel=3,
        )
    elif "model" in legacy:
        if model is not None:
            raise TypeError("em_fit() got the model twice: as the first argument and as model=")
        model = legacy["model"]
    if data is None:
        raise DataError("em_fit needs data: em_fit(model, data, freq=...) with a 1-D array of samples")
    return model, data


def em_fit(
    model: ModelLike | None = None,
    data: Any = None,
    /,
    *,
    freq: float | None = None,
    init: GMWMFit | ModelLike | None = "av",
    max_iter: int = 500,
    tol: float = 1e-8,
    unit: str = "u",
    weights: str = "efficient",
    **legacy: Any,
) -> GMWMFit:
    """Constrained EM estimate of a state-space error model (module docstring; docs/guide/theory.rst, 'Baselines').

    Same argument order as :func:`imunoise.noise.estimator.gmwm`: ``em_fit(model, data, freq=...)``.

    Parameters
    ----------
    model
        The structure: a process, a Model or a model string (:func:`imunoise.noise.model.as_model`); its
        parameters, if any, are ignored (use ``init=``). ``None``: the structure of ``init``.
    data
        One 1-D array (segments are joined after removing each one's mean; EM needs one time line).
    freq
        Sample rate in Hz, required (keyword; none is assumed; a number, else :class:`DataError`).
    init
        ``"av"`` (the AV baseline, default), a fit, or a model (process, Model or string) with
        parameters.
    max_iter, tol
        Iteration limit and relative log-likelihood tolerance.
    unit
        Data unit for summaries: ``"u"`` or a unit the CLI knows (else :class:`UnitError`).
    weights
        Ω of the reported GMWM objective.
    **legacy
        ``model=``/``data=`` as keywords; ``em_fit(data, model=...)`` (the old order) is accepted with a
        DeprecationWarning for one release.

    Returns
    -------
    GMWMFit
        ``method="em"``, ``objective`` = the GMWM objective (Eq. 8) of the EM model on the data's WV and
        Ω, and ``extra`` with iterations, log-likelihood (history too), time, convergence and divergence
        flags.
    """
    t0 = time.perf_counter()
    model, data = _em_arguments(model, data, legacy)
    freq = required_freq(freq, "em_fit")
    unit = check_unit(unit)
    if model is not None:
        model = as_model(model)
        check_em_kinds(model)  # before the AV start is computed
    if isinstance(data, (list, tuple)):
        y = np.concatenate([np.asarray(s, dtype=float) - np.mean(s) for s in data])
    else:
        y = np.asarray(data, dtype=float).reshape(-1)
    if y.size < 32:
        raise DataError(f"only {y.size} samples; the EM baseline needs at least 32")
    if not np.all(np.isfinite(y)):
        raise DataError("the data contain NaN or Inf; remove or interpolate them before EM")
    y = np.ascontiguousarray(y - y.mean())
    var_y = float(np.var(y))
    if not var_y > 0:
        raise DataError("the data are constant; EM cannot estimate a noise model")
    if isinstance(init, str) and init == "av":
        from imunoise.noise.allan import allan_fit

        init = allan_fit(y, freq=freq, unit=unit).model
    elif init is not None and not isinstance(init, GMWMFit):
        init = as_model(init)
    init_model = init.model if isinstance(init, GMWMFit) else init
    if init_model is not None and not init_model.known:
        init_model = None
    structure = model if model is not None else init_model
    if structure is None:
        raise ModelError("give the EM a model structure (model=) or a starting fit (init=)")
    structure = structure.unknown()
    check_em_kinds(structure)
    current = _start_model(structure, init_model, var_y)
    n = y.size
    tt = np.arange(n, dtype=float) - (n - 1) / 2.0
    stt = float(tt @ tt)
    has_dr = structure.has("DR")
    floor = 1e-14 * var_y
    history: list[float] = []
    best = (-math.inf, current)
    diverged = False
    decreases = 0
    converged = False
    it = 0
    while it < max_iter:
        it += 1
        phi, q, r, p0, omega, labels = state_form(current, var_y)
        ll, S00, S11, S10, e2, ty = kalman_estep(y, tt, omega, phi, q, r, p0)
        if not math.isfinite(ll):
            diverged = True
            break
        history.append(ll)
        if ll > best[0]:
            best = (ll, current)
        if len(history) >= 2:
            change = history[-1] - history[-2]
            if change < -1e-9 * abs(history[-2]):
                decreases += 1
            if abs(change) <= tol * abs(history[-1]):
                converged = True
                break
        # M-step with projection onto the constraints
        new_ar, new = [], {}
        for i, lab in enumerate(labels):
            if lab == "RW":
                new["RW"] = max((S11[i] - 2.0 * S10[i] + S00[i]) / (n - 1), floor)
            else:
                ph = float(np.clip(S10[i] / max(S00[i], 1e-300), _PHI_LO, _PHI_HI))
                s2 = max((S11[i] - 2.0 * ph * S10[i] + ph * ph * S00[i]) / (n - 1), floor)
                new_ar.append(AR1(phi=ph, sigma2=s2))
        comps: list = list(new_ar)
        if has_dr:
            comps.append(DR(omega=ty / stt))
        # σ²_WN from the residual of the updated drift: E[(y − Hx − ωtt)²] = e2 + (ω_old − ω_new)-terms;
        # with the drift re-estimated on the same smoothed states the exact update is e2 + Δω²·stt
        # − 2Δω·Σtt·e, and Σtt·e = ty − ω_old·stt
        if has_dr:
            d_om = ty / stt - omega
            e2_new = e2 - 2.0 * d_om * (ty - omega * stt) + d_om * d_om * stt
        else:
            e2_new = e2
        comps.append(WN(sigma2=max(e2_new / n, floor)))
        if "RW" in new:
            comps.append(RW(gamma2=new["RW"]))
        current = Model(comps)
    if diverged and best[0] == -math.inf:
        raise FitError("EM: the log-likelihood is not finite at the start; check the data and the start model")
    ll_best, final = best
    problem = prepare(y, freq=freq, weights=weights)
    fit = GMWMFit.from_problem(
        problem,
        final,
        converged=converged and not diverged,
        method="em",
        unit=unit,
        iterations=it,
        extra={
            "loglik": ll_best,
            "loglik_history": history,
            "iterations": it,
            "converged": converged,
            "diverged": diverged,
            "decreases": decreases,
            "start": str(init_model.params) if init_model is not None else "default",
            "data_span": {"n_samples": int(n), "n_segments": 1, "duration_s": n / float(freq)},
        },
    )
    fit.elapsed_s = time.perf_counter() - t0
    fit.extra["time_s"] = fit.elapsed_s
    return fit
