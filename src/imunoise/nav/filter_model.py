"""The one door from a fitted noise model into the filter: :func:`filter_model` per axis, :func:`filter_axis_models`
for the six axes. Every entry goes through it: the online engine's fits (:mod:`imunoise.online.to_filter`, its
settings adapter), a model file given to ``nav --imu-model`` or ``online --imu-model``
(:func:`imunoise.nav.defaults.load_axis_models`) and the experiments' fixed-model baselines.

What the filter can hold (docs/guide/theory.rst, 'Navigation filter', the rules measured in
:mod:`imunoise.online.navigator`, "From a GMWM fit to
filter noise"): an AR1 with ``fold_tau_s`` ≤ T_c and T_c·f ≤ ``horizon`` stays a Gauss–Markov state; everything
else becomes the white noise + random walk of :func:`imunoise.noise.equivalent_noise.equivalent_noise`, the mapping the
export uses too (WN, RW exact; a faster AR1 white with its zero-frequency density; QN white or dropped; an AR1
slower than the data matched over the data's scales; MA1 white with its zero-frequency density); a part that
collapsed to zero amplitude in the fit is dropped (it would make P ill-conditioned). A process that declares its
own filter states (``Process.keeps_filter_state``, e.g. a sinusoid's 2-state oscillator) passes as it is.

The drift DR, decided once here: when the data's longest scale is known (a fit carries its WV, ``horizon``), DR
becomes the random walk with the same WV at that scale (:func:`dr_equivalent_rw`). Over the scales a static
record covers, a ramp and a random walk are two readings of one rising WV, and a ramp state would extrapolate
one fitted slope over the whole drive (a slope the WV cannot even sign: it sees ω² only), while the random walk
lets the filter track a bias that keeps wandering at the rate the data showed. Without a horizon (a model
written by hand or the simulator's truth, which carry no WV) nothing says at which scale to match a random walk,
and the model itself is the statement: DR stays the ramp state it describes. Before this module ``nav
--imu-model`` kept every DR as a ramp; a fit file with a WV now gets the random walk the online engine uses.

Floor: the online engine bounds its own fits of short stops from below by the plain default (``floor``); a model
file is the user's statement and is taken without a floor (``online --no-floor`` makes the engine do the same).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.noise.equivalent_noise import data_horizon, dr_equivalent_rw, equivalent_noise
from imunoise.noise.model import Model
from imunoise.noise.processes import AR1, DR, RW, WN, Process, StateBlock

__all__ = ["NEGLIGIBLE", "AxisFit", "InMotionFilter", "filter_model", "filter_axis_models", "in_motion_filter",
           "in_motion_of", "moving_state_rows", "with_moving_states", "data_horizon", "dr_equivalent_rw"]

NEGLIGIBLE = 1e-12  # relative stationary variance below which a fitted part is treated as absent


class AxisFit(NamedTuple):
    """A fitted model of one axis as the door needs it: parameters per sample at ``freq`` [Hz] and the longest
    Haar scale of the data it was fitted on (``horizon``, samples at ``freq``; None when unknown)."""

    model: Model
    freq: float
    horizon: float | None


def filter_model(model: Model, freq: float | None = None, floor: Model | None = None, *, fold_tau_s: float = 1.0,
                 dr: str | None = None, horizon: float | None = None, qn: str = "white") -> Model:
    """Filter model of one axis from a fitted model (module docstring).

    Parameters
    ----------
    model : Model
        Known parameters per sample at its rate.
    freq : float, optional
        Sample rate of the parameters [Hz]: the model's own (given only for a model without one; a different
        one is refused, :meth:`~imunoise.noise.model.Model.sample_rate`).
    floor : Model, optional
        A WN + RW + AR1 model at ``freq``: bounds the white variance and γ² from below and contributes its AR1
        when the model has no AR1 at least as slow.
    fold_tau_s : float
        AR1s with T_c below it [s] become white.
    dr : {"rw", "drop", "state"}, optional
        DR as the random walk with its WV at the horizon, dropped, or kept as a ramp state; default (None):
        "rw" when ``horizon`` is known, else "state" (module docstring).
    horizon : float, optional
        Longest Haar scale of the fitted data [samples at ``freq``].
    qn : {"white", "drop"}
        QN as white noise (2Q² per sample) or dropped.

    Returns
    -------
    Model
        Carrying ``freq``.
    """
    freq = model.sample_rate(freq, "the filter door")
    dr = dr or ("state" if horizon is None else "rw")
    ar1: list[tuple[float, float]] = []
    ramp = None
    rest: list = []
    kept: list = []  # processes that declare their own filter states (Process.keeps_filter_state), kept as they are
    for c in model.components:
        if type(c).keeps_filter_state:
            kept.append(c)
        elif c.kind == "AR1":
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
                    raise ModelError("filter_model: a DR maps to a random walk at the data's longest scale; "
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
    comps += [c for c in kept if _stationary_variance(c) > NEGLIGIBLE * total]
    if white > 0:
        comps.append(WN(sigma2=white))
    if gamma2 > NEGLIGIBLE * max(total, 1e-300):
        comps.append(RW(gamma2=gamma2))
    if ramp is not None:
        comps.append(DR(omega=ramp))
    if not comps:
        comps.append(WN(sigma2=1e-30))
    return Model(comps, freq)


def _stationary_variance(c: Process) -> float:
    """The variance a kept process adds to the sensor error (h P0 hᵀ of its own states)."""
    _, own = c.filter_block(1.0, 1.0)
    if isinstance(own, StateBlock):
        h = own.h
        return float(sum(h[i] * own.p0[i][j] * h[j] for i in range(len(h)) for j in range(len(h))))
    return float(sum(st.h * st.h * st.p0 for st in own))


def filter_axis_models(fits: list, freq: float, floor: list[Model | None], *, fold_tau_s: float = 1.0,
                       dr: str | None = None, qn: str = "white") -> list[Model]:
    """The six models the filter gets from per-axis fits (gyro x,y,z, accel x,y,z), each carrying its rate.

    Parameters
    ----------
    fits : list
        Per axis a :class:`~imunoise.noise.estimator.GMWMFit` (or anything with ``model``, ``freq`` and optionally
        ``wv``: converted to ``freq`` with :meth:`Model.at_rate`), an :class:`AxisFit` (kept at its own rate), a
        bare :class:`Model` (kept at its own rate, ``freq`` when it has none; no horizon), or None (the axis'
        ``floor`` model as it is).
    freq : float
        Filter (IMU) rate [Hz].
    floor : list
        Per axis the floor model at ``freq`` (:func:`filter_model`), or None for none.
    fold_tau_s, dr, qn
        As for :func:`filter_model`.

    Returns
    -------
    list of Model
    """
    out = []
    for a, f in enumerate(fits):
        if f is None:
            out.append(floor[a].with_freq(floor[a].sample_rate(freq, "the floor")))
            continue
        rate, model, horizon = freq, f, None
        if isinstance(f, Model) and f.freq is not None:  # a bare model: mapped at the rate it carries
            rate = f.freq
        elif isinstance(f, AxisFit):  # a model file's axis: mapped at the rate its parameters are given at
            rate, model, horizon = f.freq, f.model, f.horizon
        elif hasattr(f, "model"):  # per sample at the fit's own rate: the same continuous-time model at freq
            model, horizon = f.model.at_rate(float(f.freq), freq), data_horizon(f)
            if horizon is not None and float(f.freq) != freq:
                horizon = horizon * freq / float(f.freq)
        fl = floor[a] if rate == freq else None
        out.append(filter_model(model, rate, fl, fold_tau_s=fold_tau_s, dr=dr, horizon=horizon, qn=qn))
    return out


class InMotionFilter(NamedTuple):
    """What the door gives the filter for a model with an in-motion part: the six models of the static part
    (each with its rate), each axis with a moving bias wander plus its Gauss–Markov as the last AR1 (the moving
    state, evolving while moving, frozen at stops: :class:`imunoise.nav.noise_schedule.NoiseControl`); ``white``:
    per axis the white-PSD scale while moving (the white factor squared); ``gm_axes``: per axis whether it has the
    moving state; ``gm_index``: per axis the index of the moving state's AR1 in its model's ``components`` (−1
    where none): the one appended, wherever :class:`~imunoise.noise.model.Model`'s ordering of its AR1s by φ put
    it, even beside a static AR1 of the same φ."""

    models: list
    white: tuple[float, ...]
    gm_axes: tuple[bool, ...]
    gm_index: tuple[int, ...]


def in_motion_filter(models: list, white_factor, gm_sigma, gm_tau_s) -> InMotionFilter:
    """The filter of the in-motion part (docs/guide/theory.rst, 'In-use noise') on top of the static models the
    door mapped (:func:`filter_axis_models`): per axis j with σ_j > 0 an AR1 φ = e^{−1/(τ_j f)}, q = σ_j²(1 − φ²)
    appended (P0 = σ_j²), and the white scale ``white_factor_j²`` while moving.

    Parameters
    ----------
    models : list of Model
        The six static filter models, each carrying its rate.
    white_factor, gm_sigma, gm_tau_s : sequence of 6 floats
        The white factor (σ scale), the moving GM σ [unit] and τ [s] per axis (σ = 0: no moving state).
    """
    moving: list[AR1 | None] = []
    for m, s, tau in zip(models, gm_sigma, gm_tau_s, strict=True):
        f = m.sample_rate(None, "the in-motion filter")
        ar1 = None
        if s > 0:
            phi = math.exp(-1.0 / (float(tau) * f))
            ar1 = AR1(phi=phi, sigma2=float(s) ** 2 * (1.0 - phi * phi))
        moving.append(ar1)
    out, index = with_moving_states(models, moving)
    return InMotionFilter(out, tuple(float(w) ** 2 for w in white_factor), tuple(bool(s > 0) for s in gm_sigma),
                          index)


def with_moving_states(models: list, moving: Sequence[AR1 | None]) -> tuple[list, tuple[int, ...]]:
    """Each axis' model of ``models`` (each carrying its rate) with its moving Gauss–Markov state ``moving[j]``
    appended (None: the model unchanged), and per axis the index of that AR1 in the new model's ``components``
    (−1 where none), found by identity: :class:`~imunoise.noise.model.Model` orders its AR1s by φ, and a static
    AR1 of the same τ has the same φ, so a value cannot tell the two apart (:func:`moving_state_rows` finds the
    state in a filter's layout)."""
    out, index = [], []
    for m, ar1 in zip(models, moving, strict=True):
        k = -1
        if ar1 is not None:
            m = Model([*m.components, ar1], m.sample_rate(None, "the moving states"))
            k = next(i for i, c in enumerate(m.components) if c is ar1)
        out.append(m)
        index.append(k)
    return out, tuple(index)


def moving_state_rows(models: list, gm_index: Sequence[int], labels: Sequence[str]) -> np.ndarray:
    """Per axis the row of its moving state among a filter's model states (``labels``: the
    :class:`~imunoise.nav.error_states.ModelLayout`'s, ``"<axis>.<component name>"``, built on ``models``), −1
    where none: the state of component ``gm_index[j]`` (:func:`with_moving_states`), by its canonical name."""
    rows = np.full(6, -1, dtype=np.int64)
    for a, (m, k) in enumerate(zip(models, gm_index, strict=True)):
        if k >= 0:
            rows[a] = list(labels).index(f"{AXES[a]}.{m.component_names()[k]}")
    return rows


def in_motion_of(src, models: list) -> InMotionFilter | None:
    """The in-motion filter of a model file (path or parsed JSON) on top of its static ``models``
    (:func:`imunoise.nav.defaults.load_axis_models`), or None when the file has no in-motion part (the filter is
    then the static model's, unchanged)."""
    from collections.abc import Mapping

    from imunoise.noise.imu_model import read_model_json
    from imunoise.noise.in_motion import InMotionPart

    d = src if isinstance(src, Mapping) else read_model_json(src)
    if not isinstance(d, Mapping) or d.get("in_motion") is None:
        return None
    part = InMotionPart.from_dict(d["in_motion"])
    sig, tau = part.moving_gm()
    return in_motion_filter(models, part.white_factors(), sig, tau)
