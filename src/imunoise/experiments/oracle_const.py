"""The constant-model ceiling ``oracle_const``: the ``in_use`` model family (a static model plus, while moving, one
white factor and one bias wander per axis, fixed for the whole drive:
:func:`imunoise.nav.filter_model.in_motion_filter`) with its parameters computed from the simulator's truth on
the scored drive itself — no estimate. It answers how much of ``oracle_law``'s gain a *perfect* constant in-motion
model keeps: what ``in_use`` could reach with unlimited data.

The static part is the truth's, mapped as ``oracle_law`` maps it (:func:`imunoise.experiments.oracle_law.law_models`:
the online engine's mapping, no floor), not ``gmwm``'s fits: then ``oracle_law`` and ``oracle_const`` differ only in
how they carry the law (per sample against one constant per axis), and ``oracle_law`` / ``oracle_const`` is the
model-family gap alone; ``in_use`` / ``oracle_const`` is the estimation gap (static and in-motion parts together).

The constant in-motion part per axis j, from the drive's :class:`~imunoise.sim.law_schedule.LawSchedule` over the
filter's moving samples M (those where ``in_use`` applies its in-motion part: the drive's known stops, from the
filter's start; T_M = |M|/f their time, f the IMU rate):

* white factor: f_j² = (⟨m_w²⟩ W_j + ⟨m_b²⟩ F_j) / (W_j + F_j), ⟨·⟩ the mean over M, W_j the true white PSD and F_j
  the short AR1 noise the mapping folds into the filter's white PSD (``oracle_law`` scales that part by m_b²): the
  constant white PSD that injects, over the moving time, the same variance as the law;
* wander driving density K_j² [unit²/s] = 2σ²_gm/τ_gm (the moving Gauss–Markov, constant by construction)
  + Σ_c (⟨m_b²⟩ − 1)⁺ q_c f over the filter's bias states c (RW γ², AR1 σ²(1 − φ²) per sample: the extra driving
  noise the multiplier adds while moving, time-averaged) + n_dep σ²_step / T_M (the departure steps of the drive,
  spread over the moving time: the bias variance they add by the drive's end, as a walk) + q_warm T / T_M (the
  warm-up's closest walk, ``oracle_law``'s own approximation, evolving in motion only here);
* wander correlation time: τ_gm where the law has a moving GM (the law's own); else the τ of the filter bias state
  with the largest extra driving noise; where that is a random walk, a departure step or the warm-up, τ = T_M
  (a walk over the drive; the family's random walk, τ = 10⁶ s, would start the wander with P0 = K²·5·10⁵,
  a variance the truth reaches only after 10⁶ s of motion, so T_M is the more favourable choice).
  σ_j = K_j √(τ_j/2) (the GM with that driving density; P0 = σ_j²).

That is the time-average of what the law injects, the constant model matching its integrated variance over the drive;
the one approximation is that mixed bias processes share one τ per axis (the family has one wander per axis).
Per axis, not per sensor group as ``in_use`` estimates: the most favourable constant model of the family.

``oracle_const_gmwm`` puts the same constant in-motion part (the factor and wander above) on ``in_use``'s own static
part (the ``gmwm`` row's fits on the vehicle's earlier drives): ``in_use`` / ``oracle_const_gmwm`` is then the gap
of the in-motion estimate alone, ``oracle_const_gmwm`` / ``oracle_const`` that of the static part.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES

__all__ = ["ConstantInMotion", "constant_in_motion", "true_static_models", "run_windows_const"]


@dataclass(frozen=True)
class ConstantInMotion:
    """The constant in-motion part per axis (gyro x, y, z, accel x, y, z): white factor (σ scale), the wander's
    σ [rad/s or m/s²] and τ [s] (σ = 0: no wander), its driving density K [unit/√s]; the moving time T_M [s]."""

    white_factor: tuple[float, ...]
    sigma: tuple[float, ...]
    tau_s: tuple[float, ...]
    k: tuple[float, ...]
    moving_s: float


def true_static_models(sc, base=None) -> list:
    """The six static filter models of the truth (each with its rate), mapped as ``oracle_law`` maps them (the
    online engine's mapping with no floor)."""
    from imunoise.experiments.common import filter_models
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN
    from imunoise.online import OnlineConfig

    static = sc.extra.get("static_models")
    if not static or sc.extra.get("law_schedule") is None:
        raise ModelError("the oracle_const method needs a simulated scenario with its true static models and its "
                         "motion law (law_schedule): run it with --sim")
    none = Model([WN(sigma2=1e-30)])
    cfg = (base or OnlineConfig()).with_(ekf=sc.ekf_config(), floor="none")
    return filter_models([static.get(ax, none) for ax in AXES], sc.rate, cfg)


def _filter_start(sc) -> int:
    """The drive sample the filter starts from (its first sample: the last IMU sample at or before ``sc.init.t``)."""
    t = np.asarray(sc.imu.t, dtype=float)
    return int(np.searchsorted(t, sc.init.t, side="right")) - 1


def constant_in_motion(sc, models: list) -> ConstantInMotion:
    """The constant in-motion part of drive ``sc`` (module docstring) on top of the static filter models ``models``
    (:func:`true_static_models`)."""
    from imunoise.inuse.likelihood import drive_moving
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN

    sched = sc.extra["law_schedule"]
    i0 = _filter_start(sc)
    mv = drive_moving(sc)[i0:]
    f = float(sc.rate)
    t_m = float(np.count_nonzero(mv)) / f
    if t_m <= 0:
        raise ModelError(f"oracle_const: drive {sc.name} never moves after the filter's start; nothing to model")
    wsc = np.asarray(sched.white_var_scale, dtype=float)[i0:][mv].mean(axis=0)
    bsc = np.asarray(sched.bias_var_scale, dtype=float)[i0:][mv].mean(axis=0)
    dep = np.asarray(sched.departure_index, dtype=np.int64)
    n_dep = int(np.count_nonzero(dep > i0))  # a departure is the step into a moving sample after the filter's start
    duration = float(sched.t[-1] - sched.t[0])
    none = Model([WN(sigma2=1e-30)])
    wf, sig, tau, kk = [], [], [], []
    for a, m in enumerate(models):
        true_white = sc.extra["static_models"].get(AXES[a], none).white_variance() / f
        w_filter = m.white_variance() / f
        folded = max(w_filter - true_white, 0.0)
        wf.append(math.sqrt((wsc[a] * true_white + bsc[a] * folded) / w_filter) if w_filter > 0 else 1.0)
        extra = max(float(bsc[a]) - 1.0, 0.0)
        parts: list[tuple[float, float]] = []  # (driving density [unit²/s], τ [s] or inf for a walk)
        for c in m.components:
            if c.kind == "RW":
                parts.append((extra * float(c.values[0]) * f, math.inf))
            elif c.kind == "AR1":
                phi, s2 = (float(x) for x in c.values)
                parts.append((extra * s2 * (1.0 - phi * phi) * f, -1.0 / (f * math.log(phi))))
        parts.append((n_dep * float(sched.step_var[a]) / t_m, math.inf))
        parts.append((float(sched.warmup_rw_q[a]) * duration / t_m, math.inf))
        k2 = sum(p[0] for p in parts)
        s_gm, tau_gm = float(sched.gm_sigma[a]), float(sched.gm_tau_s[a])
        if s_gm > 0:
            k2 += 2.0 * s_gm * s_gm / tau_gm
            ta = tau_gm
        elif k2 > 0:
            ta = max(parts, key=lambda p: p[0])[1]
            ta = t_m if math.isinf(ta) else ta
        else:
            ta = 60.0  # no wander: σ = 0 below, τ unused
        kk.append(math.sqrt(k2))
        tau.append(ta)
        sig.append(math.sqrt(k2 * ta / 2.0))
    return ConstantInMotion(tuple(wf), tuple(sig), tuple(tau), tuple(kk), t_m)


def run_windows_const(sc, gnss, windows, *, base=None, nees: bool = False,
                      models: list | None = None) -> dict[str, Any]:
    """:func:`imunoise.experiments.dense.run_windows`'s keys for ``oracle_const`` on drive ``sc``: the ``in_use``
    filter and protocol (:func:`imunoise.experiments.in_use_method.in_motion_law_filter`) with the truth's constant
    model, returned under ``oracle_const``. ``models``: another static part (``oracle_const_gmwm``: ``in_use``'s
    own) under the same constant in-motion part (white factor, σ, τ computed on the truth's static model)."""
    from imunoise.experiments.in_use_method import in_motion_law_filter
    from imunoise.experiments.oracle_law import run_windows_law

    true_models = true_static_models(sc, base)
    part = constant_in_motion(sc, true_models)
    static = true_models if models is None else models
    res = run_windows_law(sc, gnss, windows, base=base, nees=nees,
                          make=lambda s, starts, b: in_motion_law_filter(s, static, part.white_factor, part.sigma,
                                                                         part.tau_s, starts, b))
    res["oracle_const"] = {"white_factor": list(part.white_factor), "sigma": list(part.sigma),
                           "tau_s": list(part.tau_s), "k": list(part.k), "moving_s": part.moving_s}
    return res
