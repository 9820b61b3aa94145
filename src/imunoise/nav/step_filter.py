"""Step filter :class:`LooselyCoupledEKF`, one call per sample or fix (docs/guide/theory.rst, 'Navigation filter').

The equations are in :mod:`imunoise.nav.ekf`; the update functions it calls are the batch loop's
(:mod:`imunoise.nav.filter_loop`), so a run fed sample by sample equals :func:`~imunoise.nav.ekf.run_ekf`. The
measurement updates (GNSS position and velocity, ZUPT, ZARU, a generic (dz, H, R)) are
:class:`~imunoise.nav.step_updates.StepUpdates`, a mixin of the filter; propagation, spans, model swaps and the
solution are here.
"""

from __future__ import annotations

import logging

import numpy as np

from imunoise.errors import DataError
from imunoise.nav.defaults import EkfConfig, default_axis_models, normalize_axis_models
from imunoise.nav.ekf_kernels import sensor_errors_of
from imunoise.nav.error_states import ModelLayout, initial_covariance, scale_spec, swap_map
from imunoise.nav.filter_loop import (
    C_NHC_REJECT,
    C_SAMPLES,
    FilterArrays,
    ImuInput,
    ModelArrays,
    Outputs,
    Settings,
    flush,
    new_outputs,
    predict_step,
    run_steps,
    span_outputs,
)
from imunoise.nav.measurements.gnss_velocity import GnssVelocity
from imunoise.nav.measurements.nhc import NHC_OFF, NhcConfig, NhcSettings
from imunoise.nav.mechanization import make_nav, nav_euler
from imunoise.nav.rehearsal import rehearse
from imunoise.nav.state import ACC_LEN, I_DTH, I_DV, I_PREV, N_NAV, InitialState, StateView
from imunoise.nav.step_updates import Innovation, StepUpdates
from imunoise.nav.streams import S_REJECT, Stream, StreamSet, make_stream

log = logging.getLogger("imunoise.nav.ekf")  # the filter's one logger name
_NONE = (np.empty(0), np.empty((0, 0)), np.empty((0, 0)))  # predict_step's "no NHC" arrays

__all__ = ["LooselyCoupledEKF", "new_outputs"]


class LooselyCoupledEKF(StepUpdates):
    """Step-by-step EKF (docs/guide/theory.rst, 'Navigation filter'); the batch form is :func:`~imunoise.nav.run_ekf`.

    ``propagate(dtheta, dv, t)`` takes one IMU increment over (t_prev, t]; ``update_gnss(t, llh, sigma)``
    a fix at time t ≤ the current filter time (it is referred to the filter epoch with the velocity).

    Parameters
    ----------
    config : EkfConfig
        Noise, gating and update settings.
    axis_models
        Error model of each sensor axis (:func:`~imunoise.nav.defaults.normalize_axis_models`): ``None`` for the
        defaults, six models that carry their rate, or ``{"gyro": ..., "accel": ...}`` ((model, freq) pairs:
        deprecated).
    init : InitialState
        State at the start.
    imu_rate_hz : float
        Nominal IMU rate [Hz] (and the rate of a deprecated pair given with freq 0).

    Attributes
    ----------
    last_innovation : tuple or None
        ``(t, ν, S, used)`` of the last GNSS fix: innovation ν (NED m), its predicted covariance
        S = HPHᵀ + R before the update, and whether the gate let it in; read-only (for
        :mod:`imunoise.nav.adaptive`).
    last_update : imunoise.nav.step_updates.Innovation or None
        The last measurement of any kind (:class:`~imunoise.nav.step_updates.Innovation`: kind, t, y, S, K, NIS,
        used), as filterpy's ``KalmanFilter`` keeps ``y``, ``S`` and ``K``.
    """

    def __init__(self, config: EkfConfig, axis_models, init: InitialState, *, imu_rate_hz: float = 100.0):
        self.config = config
        self.dt_nom = 1.0 / float(imu_rate_hz)
        self.layout = ModelLayout.build(
            normalize_axis_models(axis_models, imu_rate_hz), self.dt_nom, scale_spec(config)
        )
        fb = ModelLayout.build(default_axis_models(imu_rate_hz, config.fallback), self.dt_nom)
        self.wpsd_fb = fb.wpsd
        self.t = float(init.t)
        self.nav = make_nav(init.llh, init.vel_ned, init.euler)
        self.xm = np.zeros(self.layout.nm)
        for a in range(6):
            b = self.layout.index(a)[0]
            self.xm[b] = (init.gyro_bias if a < 3 else init.accel_bias)[a % 3]
        self.P = initial_covariance(config, self.layout)
        self.acc = np.zeros(ACC_LEN)
        self.lever = np.asarray(config.lever_arm, dtype=float)
        self.gate_open = False
        self.n_rejected = 0
        self._consecutive_reject = 0
        # (t, ν, S = HPHᵀ + R, used) of the last GNSS fix, for innovation-based adaptation (read-only)
        self.last_innovation: tuple[float, np.ndarray, np.ndarray, bool] | None = None
        self.last_update: Innovation | None = None
        self._k = 0  # samples propagated (the NHC schedule counts them as the batch loop does)
        self._nhc_on = config.aid(NhcConfig) is not None
        self._nhc_reject = 0  # consecutive NHC rejections (the batch loop keeps the same count)
        self._parts: tuple | None = None
        self._vel_reject = 0  # consecutive GNSS velocity rejections (the velocity gate forces one in after some)

    # -- named views and kernel arguments -------------------------------------------------------
    @property
    def view(self) -> StateView:
        """Named views of the current state (``view.vel``, ``view.P_vel``, ...; :mod:`imunoise.nav.state`)."""
        return StateView(self.nav, self.P, self.xm)

    def arrays(self) -> FilterArrays:
        """The state arrays as the kernels take them (the filter's own arrays, not copies)."""
        return FilterArrays(self.nav, self.xm, self.P, self.acc)

    def nhc_settings(self) -> NhcSettings:
        """The kernel's NHC settings (``EkfConfig.aiding``; every = 0 when off)."""
        c = self.config.aid(NhcConfig)
        return NHC_OFF if c is None else c.kernel()

    def kernel_parts(self) -> tuple[ModelArrays, Settings]:
        """The model layout and settings every kernel call takes, built in this one place (kept until the
        layout changes: :meth:`swap_model`)."""
        L, c = self.layout, self.config
        if self._parts is None or self._parts[0] is not L:
            model = ModelArrays(L.phi_pow, L.q_pow, L.hvec, L.axis_of, L.wpsd, self.wpsd_fb, L.scale_index)
            settings = Settings(float(c.gate_q_scale), float(self.dt_nom), int(c.cov_every), float(c.chi2_gate),
                                int(c.gate_max_reject), float(c.gate_abs_m), int(c.zupt_every), float(c.zupt_sigma))
            self._parts = (L, model, settings)
        return self._parts[1], self._parts[2]

    # -- measurement streams ------------------------------------------------------------------------
    def position_stream(self, t, llh, sigma, *, with_nll: bool = False) -> Stream:
        """GNSS antenna position fixes (sorted; σ as given) with the filter's gate: χ² ``chi2_gate`` with the
        ``gate_abs_m`` floor, forced in after ``gate_max_reject`` consecutive rejections."""
        c = self.config
        return make_stream("gnss_position", t, np.asarray(llh, dtype=float).reshape(-1, 3),
                           np.asarray(sigma, dtype=float).reshape(-1, 3), self.lever, chi2=c.chi2_gate,
                           max_reject=c.gate_max_reject, gate_abs=c.gate_abs_m, with_nll=with_nll)

    def velocity_stream(self, vel: GnssVelocity) -> Stream:
        """GNSS antenna velocity fixes (:func:`~imunoise.nav.measurements.gnss_velocity.as_gnss_velocity`)
        through the χ² gate ``chi2_gate`` with the fixes' guards (floor ``vel.gate_abs``, forced in after
        ``vel.max_reject`` consecutive rejections; :mod:`~imunoise.nav.measurements.gnss_velocity`)."""
        return make_stream("gnss_velocity", vel.t, vel.vel_ned, vel.sigma_ned, self.lever, chi2=self.config.chi2_gate,
                           max_reject=vel.max_reject, gate_abs=vel.gate_abs)

    def streams(self, *streams: Stream) -> StreamSet:
        """A :class:`~imunoise.nav.streams.StreamSet` of ``streams`` with this filter's lever arm."""
        out = StreamSet(self.lever)
        for st in streams:
            out.add(st)
        return out

    def run_steps(self, imu: ImuInput, streams: StreamSet, out: Outputs, *, row0: int = 0, stop: int | None = None,
                  model: ModelArrays | None = None, carry: np.ndarray | None = None) -> np.ndarray:
        """Samples 1 … ``stop`` − 1 of ``imu`` (row 0: the filter's epoch) through the engine
        (:func:`~imunoise.nav.filter_loop.run_steps`) on this filter's arrays, with fresh counters unless
        ``carry`` is given; ``model`` replaces the model arrays (a noise schedule's,
        :mod:`imunoise.nav.noise_schedule`). Returns the carry. The filter's clock and counters are the
        caller's to set (:meth:`run_span` does)."""
        m, s = self.kernel_parts()
        c = np.array([1, 0, 0], dtype=np.int64) if carry is None else carry
        run_steps(imu, self.arrays(), m if model is None else model, s, self.nhc_settings(), streams.kernel(), c, out,
                  row0, imu.t.shape[0] if stop is None else stop)
        return c

    # -- propagation ------------------------------------------------------------------------------
    def propagate(self, dtheta: np.ndarray, dv: np.ndarray, t: float) -> None:
        """One IMU increment (Δθ rad, Δv m/s over (t_prev, t]); covariance every ``cov_every`` samples.

        Parameters
        ----------
        dtheta, dv : numpy.ndarray
            Angle [rad] and velocity [m/s] increments over (t_prev, t], body FRD, shape (3,).
        t : float
            End of the increment [s]; must exceed the filter time.
        """
        dt = float(t) - self.t
        if not dt > 0:
            raise DataError(f"IMU time must increase: got t={t} after t={self.t}")
        dth = np.asarray(dtheta, dtype=float)
        dvv = np.asarray(dv, dtype=float)
        if not (np.all(np.isfinite(dth)) and np.all(np.isfinite(dvv))):
            log.warning("non-finite IMU sample at t=%.3f skipped (propagated as zero motion)", t)
            dth, dvv = np.zeros(3), np.zeros(3)
        carry = np.array([0, self._k, self._nhc_reject], dtype=np.int64)
        model, settings = self.kernel_parts()
        rec = (np.empty(2), np.empty((2, 2)), np.empty((self.P.shape[0], 2))) if self._nhc_on else _NONE
        nhc_on, nis, ok = predict_step(self.arrays(), model, settings, self.nhc_settings(), dth, dvv, dt,
                                       self.gate_open, carry, np.empty(N_NAV), rec)
        self.t = float(t)
        self._k, self._nhc_reject = int(carry[C_SAMPLES]), int(carry[C_NHC_REJECT])
        if nhc_on:
            self._record("nhc", self.t, (nis, ok, *rec))

    def prime(self, dtheta: np.ndarray, dv: np.ndarray) -> None:
        """Give the strapdown the increment before the first one (Δθ rad, Δv m/s) for its two-sample
        coning/sculling terms; without it the first :meth:`propagate` assumes its own (bias-corrected)
        increment repeats. Call once, before the first :meth:`propagate`."""
        if self.nav[I_PREV] != 0.0:
            raise DataError("prime() must come before the first propagate(); the filter has already started")
        self.nav[I_DTH : I_DTH + 3] = dtheta
        self.nav[I_DV : I_DV + 3] = dv
        self.nav[I_PREV] = 1.0

    def flush(self) -> None:
        """Propagate the covariance (and the model-state estimates) over the increments accumulated since
        the last propagation, so P refers to the current epoch. Updates and swaps call it themselves."""
        flush(self.arrays(), *self.kernel_parts())

    def set_noise(self, model: ModelArrays) -> None:
        """Propagate P with the current noise, then take ``model`` (arrays of this layout, e.g. a moving/stopped
        schedule's, :class:`~imunoise.nav.noise_schedule.NoiseControl`) until the next call or swap."""
        self.flush()
        self._parts = (self.layout, model, self.kernel_parts()[1])

    def set_gate(self, open_: bool) -> None:
        """Angular-rate gate (docs/guide/theory.rst, 'Static detection'): open = conservative model noise."""
        self.gate_open = bool(open_)

    # -- spans of samples (the measurement updates one at a time: StepUpdates) ---------------------
    def run_span(self, imu: ImuInput, streams: StreamSet, rows: np.ndarray, pv: np.ndarray) -> np.ndarray:
        """Samples ``imu.t[1:]`` through the engine's step sequence (:func:`imunoise.nav.filter_loop.run_steps`:
        the propagation, NHC and measurement streams of :meth:`propagate`, :meth:`update_gnss` and
        :meth:`update_gnss_velocity`), with the filter's clock, gate, sample and rejection counters following
        the span. Writes ``rows[k − 1]`` per sample (:data:`~imunoise.nav.filter_loop.SPAN_COLS` layout) and,
        when ``pv`` has a row per sample, the velocity covariance.

        Returns
        -------
        numpy.ndarray
            Boolean per GNSS position fix: whether it was used (rejected ones are logged).
        """
        pos = streams.get("gnss_position")  # the other streams carry their own rejection counters
        if pos is not None:
            pos.state[S_REJECT] = self._consecutive_reject
        carry = self.run_steps(imu, streams, span_outputs(rows, pv), row0=1,
                               carry=np.array([1, self._k, self._nhc_reject], dtype=np.int64))
        self.t = float(imu.t[-1])
        self.gate_open = bool(imu.gate[-1])
        self._k, self._nhc_reject = int(carry[C_SAMPLES]), int(carry[C_NHC_REJECT])
        if pos is None:
            return np.zeros(0, dtype=bool)
        self._consecutive_reject = int(pos.state[S_REJECT])
        used = pos.status > 0
        for k in np.flatnonzero(~used):
            self.n_rejected += 1
            self.log_rejected(float(pos.t[k]), float(pos.nis[k]))
        return used

    def log_rejected(self, t: float, nis: float) -> None:
        """Log a GNSS fix the χ² gate rejected (here and for the online engine's kernel spans)."""
        log.info("GNSS fix at t=%.3f rejected (NIS %.1f > %.1f)", t, nis, self.config.chi2_gate)

    # -- model swap -------------------------------------------------------------------------------
    def swap_model(self, axis_models, *, preserve: bool = False, imu_rate_hz: float | None = None) -> dict[str, int]:
        """Swap the error models (docs/guide/theory.rst, 'Navigation filter'); returns ``{"kept": k, "reset": r}``.

        Navigation states and their covariance are kept; the new bias state of each axis takes the
        current total error estimate h·x̂ of the old states with variance h P hᵀ and cross-covariances
        P[:, old] hᵀ (an exact linear map); new AR1 states start at 0 with their stationary variance,
        new DR states at 0 with the configured σ. With ``preserve`` an old AR1/DR state that has a
        counterpart in the new model (same structure: by position; else an AR1 with the same φ) is carried
        over 1:1 instead (:func:`~imunoise.nav.error_states.swap_map`); ``kept`` counts those, ``reset``
        the states that start fresh. ``axis_models``: as for the constructor
        (:func:`~imunoise.nav.defaults.normalize_axis_models`).

        Parameters
        ----------
        axis_models
            The new error model of each axis.
        preserve : bool
            Carry matching AR1/DR states over instead of resetting them.
        imu_rate_hz : float, optional
            Rate of a deprecated pair given with freq 0 (default: the filter's nominal rate).
        """
        self.flush()
        rate = imu_rate_hz or 1.0 / self.dt_nom
        new = ModelLayout.build(normalize_axis_models(axis_models, rate), self.dt_nom, scale_spec(self.config))
        res = swap_map(self.layout, new, self.xm, self.P, initial_covariance(self.config, new), preserve=preserve)
        self.xm, self.P, self.layout = res.x, res.P, new
        return {"kept": res.kept, "reset": res.reset}

    def add_bias_variance(self, var) -> None:
        """Add ``var[a]`` to the variance of axis a's bias state (gyro x,y,z, accel x,y,z) at the current epoch."""
        self.flush()
        v = np.asarray(var, dtype=float)
        self.P[self.layout.bias_rows(), self.layout.bias_rows()] += np.where(v > 0, v, 0.0)  # ≤ 0 or NaN: none

    # -- what-if runs -------------------------------------------------------------------------------
    def rehearse(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, gnss_t: np.ndarray, gnss_llh: np.ndarray,
                 gnss_sigma: np.ndarray, **kw) -> tuple:
        """Run a copy of the filter on from its current state over samples ``t[1:]`` with the fixes ``gnss_*``
        (:func:`imunoise.nav.rehearsal.rehearse`, which documents the options and the result)."""
        return rehearse(self, t, dtheta, dv, gnss_t, gnss_llh, gnss_sigma, **kw)

    # -- output -----------------------------------------------------------------------------------
    def sensor_errors(self) -> np.ndarray:
        """Current total error estimate of the six axes (gyro x,y,z rad/s, accel x,y,z m/s²): Σ h·x̂ per axis."""
        return sensor_errors_of(self.xm, self.layout.hvec, self.layout.axis_of)

    def scale_factors(self) -> np.ndarray | None:
        """Current scale-factor estimates ŝ (gyro x,y,z, accel x,y,z; dimensionless), None when they are off."""
        idx = self.layout.scale_index
        return None if np.any(idx < 0) else self.xm[idx].copy()

    def state(self) -> dict:
        """Current solution: t, llh, vel_ned, euler, gyro/accel error estimates, 1σ of δr/δv/φ, the
        scale-factor estimates (None when off) and every model state by label."""
        e = self.sensor_errors()
        sv = self.view
        return {
            "t": self.t,
            "llh": sv.llh.copy(),
            "vel_ned": sv.vel.copy(),
            "euler": nav_euler(self.nav),
            "gyro_error": e[:3],
            "accel_error": e[3:],
            "std": sv.std_nav,
            "model_states": dict(zip(self.layout.labels, self.xm.tolist())),
            "scale_factors": self.scale_factors(),
        }
