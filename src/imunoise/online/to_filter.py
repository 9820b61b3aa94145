"""The one mapping from a static GMWM fit to the filter's noise model (docs/guide/theory.rst, 'Online engine', paper
§2.2–2.3):
:func:`ekf_axis_model` per axis, :func:`filter_axis_models` for the six axes (the online engine and the
experiments' fixed-model baselines), :func:`data_horizon` and :func:`dr_equivalent_rw`. Everything that does not
become a Gauss–Markov state goes through :func:`imunoise.noise.equivalent_noise.equivalent_noise`, the mapping the
export uses too. The rules and the measurements behind them: the docstring of :mod:`imunoise.online.navigator`
("From a GMWM fit to filter noise")."""

from __future__ import annotations

import math
from typing import Any

from imunoise.errors import ModelError
from imunoise.nav.defaults import default_axis_models
from imunoise.noise.equivalent_noise import data_horizon as _data_horizon
from imunoise.noise.equivalent_noise import dr_equivalent_rw as _dr_equivalent_rw
from imunoise.noise.equivalent_noise import equivalent_noise
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, RW, WN
from imunoise.online.config import NEGLIGIBLE, OnlineConfig

__all__ = ["data_horizon", "dr_equivalent_rw", "ekf_axis_model", "filter_axis_models"]


# --------------------------------------------------------------------------------------------------
# fit → filter model
# --------------------------------------------------------------------------------------------------
def data_horizon(fit: Any) -> float | None:
    """The longest Haar scale (samples) of the WV a fit was made on: the ``horizon`` of :func:`ekf_axis_model`;
    None when the fit carries no WV (e.g. an Allan-variance model built without one). One definition with the
    export (:func:`imunoise.noise.equivalent_noise.data_horizon`)."""
    return _data_horizon(fit)


def dr_equivalent_rw(omega: float, horizon: float) -> float:
    """γ² (per sample) of the random walk with the same Haar WV as a drift ω at scale τ = ``horizon`` samples
    (:func:`imunoise.noise.equivalent_noise.dr_equivalent_rw`, the one mapping shared with the export)."""
    return _dr_equivalent_rw(omega, horizon)


def ekf_axis_model(model: Model, freq: float, floor: Model | None = None, *, fold_tau_s: float = 1.0,
                   dr: str = "rw", horizon: float | None = None, qn: str = "white") -> Model:
    """Filter model of one axis from a static GMWM model (module docstring): AR1s with ``fold_tau_s`` ≤ T_c and
    T_c·f ≤ ``horizon`` stay Gauss–Markov states; everything else becomes the white noise + random walk of
    :func:`imunoise.noise.equivalent_noise.equivalent_noise` — the one mapping the export uses — with
    ``white_below_s = fold_tau_s``: WN, RW exact; faster AR1s white with the density σ²/(1 − φ)² per sample;
    QN as white (2Q² per sample) or dropped (``qn="drop"``); an AR1 slower than the data (T_c·f > ``horizon``)
    matched over [1/f, horizon] (≈ a random walk with its innovation variance); DR as the random walk with
    its WV at the horizon (``dr="rw"``, :func:`dr_equivalent_rw`), dropped (``dr="drop"``) or kept as a ramp
    state (``dr="state"``). ``horizon``: the longest Haar scale of the data the model was fitted on, in
    samples (required when something needs it: a DR with ``dr="rw"``, an AR1 beyond it is only detected with it).

    ``floor`` (a WN + RW + AR1 model with known parameters, per sample at ``freq``) bounds the white
    variance and γ² from below and contributes its AR1 (the slow bias instability) when the model has no
    AR1 at least as slow. Parameters per sample at ``freq``.
    """
    ar1: list[tuple[float, float]] = []
    ramp = None
    rest: list = []
    for c in model.components:
        if c.kind == "AR1":
            phi, s2 = c.values
            tc_samples = -1.0 / math.log(phi)
            if tc_samples >= fold_tau_s * freq and (horizon is None or tc_samples <= horizon):
                ar1.append((phi, s2))
            else:
                rest.append(c)  # folded into white (fast) or matched as a random walk (slower than the data)
        elif c.kind == "DR":
            if dr == "state":
                ramp = c.values[0]
            elif dr == "rw":
                if horizon is None or not horizon >= 2:
                    raise ModelError("ekf_axis_model: a DR maps to a random walk at the data's longest scale; "
                                     "pass horizon (samples, ≥ 2) or dr='drop'/'state'")
                rest.append(c)
        else:
            rest.append(c)
    white = 0.0
    gamma2 = 0.0
    if rest:
        eq = equivalent_noise(Model(rest), freq, horizon_s=None if horizon is None else horizon / (2.0 * freq),
                              white_below_s=fold_tau_s, qn=qn)
        white, gamma2 = eq.sigma2, eq.gamma2
    if floor is not None:
        for c in floor.components:
            if c.kind == "WN":
                white = max(white, c.values[0])
            elif c.kind == "RW":
                gamma2 = max(gamma2, c.values[0])
            elif c.kind == "AR1":
                phi_f, s2_f = c.values
                var_f = s2_f / (1 - phi_f**2)
                slow = [(p, s) for p, s in ar1 if p >= phi_f]
                if not slow or max(s / (1 - p * p) for p, s in slow) < var_f:
                    ar1.append((phi_f, s2_f))
    # a process that collapsed to zero amplitude in the fit (GOF keeps such "nested" components at the
    # parameter bound, σ²_GM ~ 1e-57) carries nothing and would make P ill-conditioned: drop it
    total = white + sum(s / (1 - p * p) for p, s in ar1)
    comps: list = [AR1(phi=p, sigma2=s) for p, s in ar1 if s / (1 - p * p) > NEGLIGIBLE * total]
    if white > 0:
        comps.append(WN(sigma2=white))
    if gamma2 > NEGLIGIBLE * max(total, 1e-300):
        comps.append(RW(gamma2=gamma2))
    if ramp is not None:
        from imunoise.noise.processes import DR

        comps.append(DR(omega=ramp))
    if not comps:
        comps.append(WN(sigma2=1e-30))
    return Model(comps)


def filter_axis_models(fits: list, freq: float, config: OnlineConfig | None = None,
                       floor: list[Model] | None = None) -> list[tuple[Model, float]]:
    """The six (model, freq) pairs the filter gets from per-axis fits (gyro x,y,z, accel x,y,z): each through
    :func:`ekf_axis_model` with ``config``'s ``floor``/``fold_tau_s``/``dr``/``qn``; the one six-axis loop of
    the online engine (:meth:`OnlineNavigator.filter_models`) and the experiments' fixed-model baselines.

    Parameters
    ----------
    fits : list
        Per axis a :class:`~imunoise.noise.estimator.GMWMFit` (or any fit with ``model``, ``freq`` and optionally
        ``wv``: parameters per sample at ``fit.freq``, horizon :func:`data_horizon`), a bare :class:`Model`
        (per sample at ``freq``, no horizon), or None (the plain default of ``config.ekf.fallback``).
    freq : float
        IMU rate in Hz (the rate of the returned pairs).
    config : OnlineConfig, optional
        The mapping settings (default :class:`OnlineConfig`).
    floor : list of Model, optional
        Per-axis plain default models at ``freq`` when already built (default: from ``config.ekf.fallback``).

    Returns
    -------
    list of (Model, float)
    """
    config = config or OnlineConfig()
    defaults = floor if floor is not None else [m for m, _ in default_axis_models(freq, config.ekf.fallback)]
    out = []
    for a, f in enumerate(fits):
        if f is None:
            out.append((defaults[a], freq))
            continue
        is_fit = hasattr(f, "model")
        fl = defaults[a] if config.floor == "default" else None
        model, horizon = f, None
        if is_fit:  # per sample at the fit's own rate: the same continuous-time model at the filter's rate
            model, horizon = f.model.at_rate(float(f.freq), freq), data_horizon(f)
            if horizon is not None and float(f.freq) != freq:
                horizon = horizon * freq / float(f.freq)
        out.append((ekf_axis_model(model, freq, fl, fold_tau_s=config.fold_tau_s, dr=config.dr,
                                   horizon=horizon, qn=config.qn), freq))
    return out
