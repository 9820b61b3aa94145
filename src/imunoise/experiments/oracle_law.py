"""The law-aware oracle ``oracle_law`` (issue 21 §2): the filter is told, sample by sample, what the simulator's
motion law injects — the ceiling of every error-model method under that law.

From the drive's :class:`~imunoise.sim.law_schedule.LawSchedule` and the simulator's static (true) per-axis
models, mapped to the filter as the ``oracle`` maps its models (no floor):

* white PSD of axis j times m_w² and the driving noise of its RW/AR1 states times m_b² (the short AR1s the
  mapping folds into white noise too: their part of the white PSD takes m_b²), per piece the mean of
  the schedule over the piece (so the injected variance integrated over the drive is the schedule's);
* the moving Gauss–Markov (σ_j, τ_j) as an augmented AR1 state per axis with σ_j > 0 (H = 1, P0 = σ²),
  evolving while moving and frozen at stops;
* at each departure from a stop, σ²_step,j added to the covariance of the axis' bias state;
* the warm-up b(t) = A(1 − e^{−t/τ}) is deterministic and the filter has no state for it: it gets the closest
  random walk over the drive, q_j = A_j²(1 − e^{−T/τ})²/T (:func:`~imunoise.sim.law_schedule.warmup_random_walk`),
  an approximation (the only one here).

The filter is the batch kernel run piece by piece (:func:`imunoise.nav.noise_schedule.run_pieces`), not the
online engine: the oracle needs no stops and no modelling. It keeps what the online engine does to every method's
filter, ``oracle`` included: the 30 °/s angular-rate gate (docs/guide/theory.rst, 'Static detection'; conservative noise
in sharp turns), so that under
the law ``none`` ``oracle_law`` and ``oracle`` are one filter (window drifts equal to 1e-5) and any difference
between them elsewhere is the law's. (Without it, on 10 drives of the law ``none``, ``oracle_law``/``oracle`` was
0.991 [0.968, 1.014], per window 0.69–1.05: a difference of paths, not of knowledge.) The dense-window protocol
is the one of :func:`imunoise.experiments.dense.run_windows` (one aided run, a GNSS-free branch from each window's
start).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.imu import AXES
from imunoise.nav.ekf import check_imu
from imunoise.nav.filter_loop import FilterArrays, ImuInput
from imunoise.nav.filter_model import moving_state_rows, with_moving_states
from imunoise.nav.noise_schedule import NoiseControl, add_bias_variance, run_pieces
from imunoise.nav.solution import NavSolution
from imunoise.nav.state import N_NAV
from imunoise.nav.step_filter import LooselyCoupledEKF, new_outputs
from imunoise.nav.streams import StreamSet

__all__ = ["LawFilter", "evaluate_law", "law_filter", "law_models", "law_states", "run_windows_law"]

BRANCH_MARGIN_S = 1.0


def law_models(sc, base=None) -> list:
    """The six filter models (with their rate) of ``oracle_law``: the static true models through the oracle's mapping
    (no floor), each axis with σ_j > 0 plus its moving Gauss–Markov as an AR1 (φ = e^{−1/(τ f)}, σ²(1 − φ²))."""
    return law_states(sc, base)[0]


def law_states(sc, base=None) -> tuple[list, tuple[int, ...]]:
    """:func:`law_models` and per axis the index of its moving Gauss–Markov in the model's ``components`` (−1 where
    none; :func:`imunoise.nav.filter_model.with_moving_states`: the appended AR1 itself, not the first AR1 of its φ,
    which a static AR1 of the same τ shares)."""
    from imunoise.experiments.common import filter_models
    from imunoise.noise.model import Model
    from imunoise.noise.processes import AR1, WN
    from imunoise.online import OnlineConfig

    sched = sc.extra.get("law_schedule")
    static = sc.extra.get("static_models")
    if sched is None or not static:
        raise ModelError("the oracle_law method needs a simulated scenario with its motion law (law_schedule)")
    none = Model([WN(sigma2=1e-30)])
    cfg = (base or OnlineConfig()).with_(ekf=sc.ekf_config(), floor="none")
    static_models = filter_models([static.get(ax, none) for ax in AXES], sc.rate, cfg)
    moving: list[AR1 | None] = []
    for a, m in enumerate(static_models):
        sig, tau = float(sched.gm_sigma[a]), float(sched.gm_tau_s[a])
        ar1 = None
        if sig > 0:
            phi = math.exp(-1.0 / (tau * m.freq))
            ar1 = AR1(phi=phi, sigma2=sig * sig * (1.0 - phi * phi))
        moving.append(ar1)
    return with_moving_states(static_models, moving)


def _folded_psd(sc, models: list) -> np.ndarray:
    """Per axis the part of the filter's white PSD that is folded short AR1 noise (filter white − true white)."""
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN

    none = Model([WN(sigma2=1e-30)])
    static = sc.extra["static_models"]
    out = np.zeros(6)
    for a, (m, f) in enumerate((m, m.freq) for m in models):
        true_white = static.get(AXES[a], none).white_variance() / f
        out[a] = max(m.white_variance() / f - true_white, 0.0)
    return out


@dataclass
class LawFilter:
    """A filter ready to run a drive under its law: kernel inputs and the schedule on the filter's samples."""

    ekf: LooselyCoupledEKF
    noise: NoiseControl
    imu: ImuInput
    bounds: np.ndarray  # piece starts (filter sample indices), 0 and n − 1 included
    white: np.ndarray  # (pieces, 6) mean m_w² over each piece
    bias: np.ndarray  # (pieces, 6) mean m_b²
    moving: np.ndarray  # (pieces,)
    bump: np.ndarray  # (pieces,) bool: a departure opens the piece
    step_var: np.ndarray

    def before_piece(self, f: FilterArrays, a: int):
        """Set the controls of the piece starting at sample ``a`` (bump the bias covariance at a departure)."""
        i = int(np.searchsorted(self.bounds, a, side="right")) - 1
        self.noise.set_noise_scale(self.white[i], self.bias[i])
        self.noise.set_moving(bool(self.moving[i]))
        if self.bump[i] and self.bounds[i] == a:
            add_bias_variance(f.P, self.noise.bias_index, self.step_var)
        return self.noise.arrays()


def _rate_gate(sc, base, i0: int, n: int) -> np.ndarray:
    """The online engine's angular-rate gate on the filter's samples i0 … i0 + n − 1
    (docs/guide/theory.rst, 'Static detection': open where
    ‖ω̃‖ > the detector's ``gate_rate``, 30 °/s; the filter then propagates with its conservative noise), so that
    ``oracle_law`` and ``oracle`` are the same filter when the law adds nothing; off with ``OnlineConfig.gate``
    False."""
    from imunoise.detect.config import DetectorConfig
    from imunoise.online import OnlineConfig

    cfg = base or OnlineConfig()
    if not cfg.gate:
        return np.zeros(n, dtype=np.bool_)
    gyro, _ = sc.imu.rates()
    w = np.linalg.norm(np.asarray(gyro, dtype=float)[i0 : i0 + n], axis=1)
    return np.ascontiguousarray(~(w <= (cfg.detector or DetectorConfig()).gate_rate))  # NaN: open, as the detector


def law_filter(sc, extra_bounds_t=(), base=None, *, models: list | None = None) -> LawFilter:
    """The ``oracle_law`` filter of scenario ``sc`` from its start ``sc.init``; ``extra_bounds_t``: times where a
    piece must start (window starts: the piece starts at the last sample before each). ``models``: fixed
    models (each carrying its rate) with the schedule off (a constant-model filter through the same batch path)."""
    sched = sc.extra["law_schedule"] if models is None else None
    gm_index: tuple[int, ...] = (-1,) * 6
    if models is None:
        models, gm_index = law_states(sc, base)
    init = sc.init
    t_all = np.asarray(sc.imu.t, dtype=float)
    dth_all, dv_all = sc.imu.increments()
    i0 = int(np.searchsorted(t_all, init.t, side="right")) - 1
    t = t_all[i0:].copy()
    t[0] = init.t
    dth = np.ascontiguousarray(dth_all[i0:], dtype=float)
    dv = np.ascontiguousarray(dv_all[i0:], dtype=float)
    if t_all[i0] < init.t and dth.shape[0] > 1:  # the first increment after init.t covers part of its interval
        frac = (t_all[i0 + 1] - init.t) / (t_all[i0 + 1] - t_all[i0])
        dth[1] *= frac
        dv[1] *= frac
    t, dth, dv = check_imu(t, dth, dv)
    n = t.size
    gate = _rate_gate(sc, base, i0, n)
    ekf = LooselyCoupledEKF(sc.ekf_config(), models, init, imu_rate_hz=sc.rate)
    ekf.prime(dth[0], dv[0])
    model, _ = ekf.kernel_parts()
    extra = np.searchsorted(t, np.asarray(extra_bounds_t, dtype=float), side="left") - 1
    if sched is None:
        bounds = np.unique(np.clip(np.concatenate([[0, n - 1], extra]), 0, n - 1)).astype(np.int64)
        k = bounds.size - 1
        return LawFilter(ekf, NoiseControl(ekf.layout, model, ekf.dt_nom), ImuInput(
            t, dth, dv, gate, np.zeros(n, dtype=np.bool_)), bounds[:-1], np.ones((k, 6)),
            np.ones((k, 6)), np.ones(k, dtype=bool), np.zeros(k, dtype=bool), np.zeros(6))
    noise = NoiseControl(ekf.layout, model, ekf.dt_nom, moving_state_rows(models, gm_index, ekf.layout.labels),
                         sched.warmup_rw_q, _folded_psd(sc, models))
    # schedule index of filter sample k (the step into k): k + i0 (schedule.t are the drive's IMU samples)
    off = i0
    cps = sched.change_points() - off - 1
    bounds = np.unique(np.clip(np.concatenate([[0, n - 1], cps, extra]), 0, n - 1)).astype(np.int64)
    ns = sched.t.size
    white, bias, moving, bump = [], [], [], []
    deps = set(int(d) for d in sched.departure_index)
    for a, b in zip(bounds[:-1], bounds[1:]):
        lo, hi = min(a + 1 + off, ns - 1), min(b + 1 + off, ns)
        white.append(sched.white_var_scale[lo:hi].mean(axis=0))
        bias.append(sched.bias_var_scale[lo:hi].mean(axis=0))
        moving.append(bool(sched.moving[lo]))
        bump.append(lo in deps)
    imu = ImuInput(t, dth, dv, gate, np.zeros(n, dtype=np.bool_))
    return LawFilter(ekf, noise, imu, bounds[:-1], np.array(white), np.array(bias), np.array(moving),
                     np.array(bump), np.asarray(sched.step_var, dtype=float))


def _fixes(gnss, ekf: LooselyCoupledEKF, keep=None) -> StreamSet:
    """The finite GNSS fixes (sorted; those ``keep`` accepts) as the filter's measurement streams."""
    gt = np.asarray(gnss.t, dtype=float)
    llh, sig = np.asarray(gnss.llh, dtype=float), np.asarray(gnss.sigma_ned, dtype=float)
    ok = np.isfinite(gt) & np.all(np.isfinite(llh), axis=1) & np.all(np.isfinite(sig), axis=1)
    if keep is not None:
        ok &= keep(gt)
    order = np.argsort(gt[ok], kind="stable")
    return ekf.streams(ekf.position_stream(gt[ok][order], llh[ok][order], sig[ok][order]))


def _solution(imu: ImuInput, out, a: int, b: int) -> NavSolution:
    return NavSolution(imu.t[a : b + 1], out.pos[a : b + 1], out.vel[a : b + 1], out.att[a : b + 1],
                       out.err[a : b + 1, :3], out.err[a : b + 1, 3:], out.std[a : b + 1])


def _run(lf: LawFilter, f: FilterArrays, fx: StreamSet, out, a: int, b: int, off: int = 0) -> None:
    """Samples a → b of the drive on state ``f``; ``out`` rows are drive samples − ``off``."""
    ekf = lf.ekf
    bounds = [a, *[int(x) for x in lf.bounds if a < x < b], b]
    if off:
        imu = ImuInput(*(x[off : b + 1] for x in lf.imu))
        run_pieces(ekf, imu, f, fx, out, [x - off for x in bounds], lambda k: lf.before_piece(f, k + off))
    else:
        run_pieces(ekf, lf.imu, f, fx, out, bounds, lambda k: lf.before_piece(f, k))


def run_windows_law(sc, gnss, windows, *, base=None, keep: bool = False, models: list | None = None,
                    nees: bool = False, make=None) -> dict[str, Any]:
    """:func:`imunoise.experiments.dense.run_windows` for ``oracle_law``: the same keys (``windows`` with
    ``drift``, ``rms``, ``drift_v``, ``aided_rms``; ``horizontal_rms_m``, ``vertical_rms_m``; ``nees`` with
    ``nees``). ``models``: a constant-model filter instead (:func:`law_filter`); ``make(sc, starts, base)``:
    another :class:`LawFilter` (``in_use``: :mod:`imunoise.experiments.in_use_method`)."""
    from imunoise.experiments.window_errors import branch_errors, window_metrics
    from imunoise.nav.metrics import nav_errors

    starts = [s for s, _ in windows]
    lf = law_filter(sc, starts, base, models=models) if make is None else make(sc, starts, base)
    ekf, t = lf.ekf, lf.imu.t
    n = t.size
    has_sf = bool(np.all(ekf.layout.scale_index >= 0))
    out = new_outputs(n, store_cov=nees, has_sf=has_sf)  # the covariance at every sample only for the NEES
    out.pos[0], out.vel[0], out.att[0] = sc.init.llh, sc.init.vel_ned, sc.init.euler
    out.err[0] = ekf.sensor_errors()
    out.std[0] = np.sqrt(np.diag(ekf.P)[:N_NAV])
    if nees:
        out.cov[0] = ekf.P[:N_NAV, :N_NAV]
    fx = _fixes(gnss, ekf)
    f = ekf.arrays()
    res_w: list[dict | None] = [None] * len(windows)
    k = 0
    for j in sorted(range(len(windows)), key=lambda j: windows[j][0]):
        s, length = windows[j]
        w = max(int(np.searchsorted(t, s, side="left")) - 1, 0)
        if w > k:
            _run(lf, f, fx, out, k, w)
            k = w
        e = min(int(np.searchsorted(t, s + length + BRANCH_MARGIN_S, side="left")), n - 1)
        if e <= w:
            res_w[j] = {"drift": None, "rms": None, "drift_v": None}
            continue
        fb = FilterArrays(*(x.copy() for x in f))
        bfx = _fixes(gnss, ekf, keep=lambda g, s=s, L=length: (g < s) | (g >= s + L))
        bout = new_outputs(e - w + 1, store_cov=False, has_sf=has_sf)
        _run(lf, fb, bfx, bout, w, e, off=w)
        sol = _solution(ImuInput(*(x[w:] for x in lf.imu)), bout, 1, e - w)
        res_w[j] = window_metrics(branch_errors(sol, sc, s), s, length)
    if k < n - 1:
        _run(lf, f, fx, out, k, n - 1)
    full = _solution(lf.imu, out, 0, n - 1)
    err = nav_errors(full.t, full.antenna_llh(sc.lever), full.vel_ned, full.euler, sc.ref)
    for j, (s, length) in enumerate(windows):
        m = (err.t >= s) & (err.t < s + length)
        h = err.horizontal[m]
        res_w[j]["aided_rms"] = float(np.sqrt(np.mean(h * h))) if h.size else None
    res: dict[str, Any] = {"windows": res_w, "horizontal_rms_m": float(np.sqrt(np.mean(err.horizontal ** 2))),
                           "vertical_rms_m": float(np.sqrt(np.mean(err.vertical ** 2)))}
    if nees:
        from imunoise.experiments.nees import drive_nees, epoch_error, nees6, scored_epochs

        res["nees"] = drive_nees([nees6(epoch_error(sc, j, out.pos[k], out.att[k], out.vel[k]), out.cov[k])
                                  for k, j in zip(*scored_epochs(sc, t), strict=True)])
    if keep:
        res["_full"] = full
    return res


def _drive_run(sc, gnss, base=None) -> tuple[NavSolution, float]:
    """One run of the whole drive with ``gnss``: the solution and the filter's wall time [s]."""
    import time

    lf = law_filter(sc, (), base)
    ekf, n = lf.ekf, lf.imu.t.size
    out = new_outputs(n, store_cov=False, has_sf=bool(np.all(ekf.layout.scale_index >= 0)))
    out.pos[0], out.vel[0], out.att[0] = sc.init.llh, sc.init.vel_ned, sc.init.euler
    out.err[0] = ekf.sensor_errors()
    out.std[0] = np.sqrt(np.diag(ekf.P)[:N_NAV])
    t0 = time.perf_counter()
    _run(lf, ekf.arrays(), _fixes(gnss, ekf), out, 0, n - 1)
    return _solution(lf.imu, out, 0, n - 1), time.perf_counter() - t0


def evaluate_law(sc, *, base=None) -> dict[str, Any]:
    """:func:`imunoise.experiments.common.evaluate` for ``oracle_law``: the full-GNSS run (position RMS) and the
    outage run(s) (end-of-outage drift), the same keys."""
    from imunoise.experiments.common import combine
    from imunoise.nav.metrics import nav_errors, summarize

    full, elapsed = _drive_run(sc, sc.gnss, base)
    err = nav_errors(full.t, full.antenna_llh(sc.lever), full.vel_ned, full.euler, sc.ref)
    m = summarize(err, elapsed_s=elapsed, duration_s=sc.duration)
    res = {k: m[k] for k in ("horizontal_rms_m", "vertical_rms_m", "ecef_rms_m", "horizontal_max_m",
                             "realtime_factor")}
    res.update(elapsed_s=elapsed, timing={}, n_updates=0)
    parts = []
    if sc.windows:
        for g in ([[w] for w in sc.windows] if sc.outage_runs else [list(sc.windows)]):
            r, _ = _drive_run(sc, sc.gnss.without(g), base)
            e = nav_errors(r.t, r.antenna_llh(sc.lever), r.vel_ned, r.euler, sc.ref)
            outs = summarize(e, outages=g)["outages"]
            parts.append({"ends": [o["end_horizontal_m"] for o in outs], "ends_v": [o["end_vertical_m"] for o in outs]})
    return combine(res, parts)
