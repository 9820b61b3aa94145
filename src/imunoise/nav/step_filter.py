"""The step filter (SPEC §8): :class:`LooselyCoupledEKF`, one call per IMU sample or measurement, for online use.

The equations are in :mod:`imunoise.nav.ekf`; the update functions it calls are the batch loop's
(:mod:`imunoise.nav.filter_loop`), so a run fed sample by sample equals :func:`~imunoise.nav.ekf.run_ekf`.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np

from imunoise.errors import DataError
from imunoise.nav.defaults import EkfConfig, default_axis_models, normalize_axis_models
from imunoise.nav.ekf_kernels import kf_update, nav_step, propagate_cov, sensor_errors_of
from imunoise.nav.error_states import ModelLayout, initial_covariance, scale_spec, swap_map
from imunoise.nav.filter_loop import (
    FilterArrays,
    Fixes,
    ImuInput,
    ModelArrays,
    Outputs,
    Settings,
    VelocityFixes,
    gnss_position_update,
    gnss_velocity_update,
    nhc_due,
    nhc_update,
    run_batch,
    run_span,
    zupt_update,
)
from imunoise.nav.measurements.gnss_velocity import GnssVelocity, as_gnss_velocity
from imunoise.nav.measurements.nhc import NHC_OFF, NhcConfig, NhcSettings
from imunoise.nav.measurements.zupt import zaru
from imunoise.nav.mechanization import make_nav, nav_euler
from imunoise.nav.state import A_LAST_DT, A_STEPS, ACC_LEN, I_DTH, I_DV, I_PREV, N_NAV, InitialState, StateView

log = logging.getLogger("imunoise.nav.ekf")  # the filter's one logger name

__all__ = ["LooselyCoupledEKF", "Innovation", "new_outputs", "velocity_fixes"]


class Innovation(NamedTuple):
    """One measurement update (filterpy's ``y``, ``S``, ``K``): its kind, time [s], innovation ``y`` = dz,
    its covariance ``S`` = HPHᵀ + R before the update, the gain ``K`` (zeros when not used), the NIS and
    whether the update was applied."""

    kind: str
    t: float
    y: np.ndarray
    S: np.ndarray
    K: np.ndarray
    nis: float
    used: bool


def velocity_fixes(vel: GnssVelocity | None, lever: np.ndarray) -> VelocityFixes:
    """The kernel's velocity fixes (none: empty arrays)."""
    vel = vel if vel is not None else as_gnss_velocity(np.zeros(0), np.zeros((0, 3)), np.ones(3))
    return VelocityFixes(vel.t, vel.vel_ned, vel.sigma_ned, lever, np.full(vel.t.size, -1, dtype=np.int64),
                         np.full(vel.t.size, np.nan))


def new_outputs(n: int, *, store_cov: bool, has_sf: bool) -> Outputs:
    """Empty per-sample outputs of :func:`~imunoise.nav.filter_loop.run_batch` for ``n`` samples."""
    return Outputs(np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 6)), np.empty((n, N_NAV)),
                   np.zeros((n if store_cov else 1, N_NAV, N_NAV)), np.zeros((n if has_sf else 1, 6)))


class LooselyCoupledEKF:
    """Step-by-step loosely coupled EKF (SPEC §8) for online use; :func:`~imunoise.nav.ekf.run_ekf` is the batch form.

    ``propagate(dtheta, dv, t)`` takes one IMU increment over (t_prev, t]; ``update_gnss(t, llh, sigma)``
    a fix at time t ≤ the current filter time (it is referred to the filter epoch with the velocity).

    Parameters
    ----------
    config : EkfConfig
        Noise, gating and update settings.
    axis_models
        Error model of each sensor axis (:func:`~imunoise.nav.defaults.normalize_axis_models`): ``None`` for the
        defaults, six models or (model, freq) pairs, or ``{"gyro": ..., "accel": ...}``.
    init : InitialState
        State at the start.
    imu_rate_hz : float
        Nominal IMU rate [Hz]; default rate of models given without one.

    Attributes
    ----------
    last_innovation : tuple or None
        ``(t, ν, S, used)`` of the last GNSS fix: innovation ν (NED m), its predicted covariance
        S = HPHᵀ + R before the update, and whether the gate let it in; read-only (for
        :mod:`imunoise.nav.adaptive`).
    last_update : Innovation or None
        The last measurement of any kind (:class:`Innovation`: kind, t, y, S, K, NIS, used), as filterpy's
        ``KalmanFilter`` keeps ``y``, ``S`` and ``K``.
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
        """The model layout and settings every kernel call takes, built in this one place."""
        L, c = self.layout, self.config
        model = ModelArrays(L.phi_pow, L.q_pow, L.hvec, L.axis_of, L.wpsd, self.wpsd_fb, L.scale_index)
        settings = Settings(float(c.gate_q_scale), float(self.dt_nom), int(c.cov_every), float(c.chi2_gate),
                            int(c.gate_max_reject), float(c.gate_abs_m), int(c.zupt_every), float(c.zupt_sigma))
        return model, settings

    def _record(self, kind: str, t: float, out: tuple) -> bool:
        nis, ok, dz, S, K = out
        self.last_update = Innovation(kind, float(t), dz, S, K, float(nis), bool(ok))
        return bool(ok)

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
        L = self.layout
        nav_step(self.nav, self.xm, self.acc, dth, dvv, dt, L.hvec, L.axis_of, self.gate_open, L.scale_index)
        self.t = float(t)
        self._k += 1
        if self.acc[A_STEPS] >= self.config.cov_every or dt > 1.5 * self.dt_nom * self.config.cov_every:
            self.flush()
        if self._nhc_on:  # the batch loop's order: NHC after the propagation, before the fixes
            f, nh = self.arrays(), self.nhc_settings()
            if nhc_due(f, nh, self._k):
                ok = self._record("nhc", self.t, nhc_update(f, *self.kernel_parts(), nh, self._nhc_reject))
                self._nhc_reject = 0 if ok else self._nhc_reject + 1

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
        L = self.layout
        propagate_cov(
            self.P,
            self.nav,
            self.xm,
            self.acc,
            L.phi_pow,
            L.q_pow,
            L.hvec,
            L.axis_of,
            L.wpsd,
            self.wpsd_fb,
            self.config.gate_q_scale,
            self.dt_nom,
            L.scale_index,
        )

    def set_gate(self, open_: bool) -> None:
        """SPEC §7 angular-rate gate: while open the stochastic states use the conservative noise."""
        self.gate_open = bool(open_)

    # -- measurements -----------------------------------------------------------------------------
    def update_gnss(self, t: float, llh: np.ndarray, sigma_ned: np.ndarray) -> bool:
        """GNSS antenna position fix (rad, rad, m) with 1σ NED (m). Returns whether it was used.

        Parameters
        ----------
        t : float
            Time of the fix [s], ≤ the filter time.
        llh : numpy.ndarray
            Antenna latitude, longitude [rad], height [m].
        sigma_ned : numpy.ndarray
            1σ North, East, Down [m]; non-finite values are replaced by ``config.gnss_sigma_nan``.

        Returns
        -------
        bool
            False when the χ² gate rejected it or the position is not finite.
        """
        llh = np.asarray(llh, dtype=float)
        sig = np.asarray(sigma_ned, dtype=float).copy()
        if not np.all(np.isfinite(llh)):
            log.warning("GNSS fix at t=%.3f has non-finite position: ignored", t)
            return False
        bad = ~np.isfinite(sig)
        sig[bad] = self.config.gnss_sigma_nan
        sig = np.maximum(sig, self.config.gnss_sigma_floor)
        force = self._consecutive_reject >= self.config.gate_max_reject
        out = gnss_position_update(self.arrays(), *self.kernel_parts(), llh, sig, self.lever, self.t - float(t), force)
        nis, ok, dz, S, _ = out
        self._record("gnss_position", t, out)
        self.last_innovation = (float(t), dz.copy(), S, bool(ok))
        if ok:
            self._consecutive_reject = 0
        else:
            self._consecutive_reject += 1
            self.n_rejected += 1
            self.log_rejected(t, nis)
        return bool(ok)

    def run_span(self, imu: ImuInput, fixes: Fixes, rows: np.ndarray, pv: np.ndarray) -> np.ndarray:
        """Samples ``imu.t[1:]`` through the batch kernel's step sequence (:func:`imunoise.nav.filter_loop.run_span`:
        propagation, NHC and GNSS fixes through the same update functions as :meth:`propagate` and
        :meth:`update_gnss`), with the filter's clock, gate, sample and rejection counters following the span.

        Returns
        -------
        numpy.ndarray
            Boolean per fix: whether it was used (the kernel writes ``fixes.status``; rejected ones are logged).
        """
        carry = np.array([self._k, self._consecutive_reject, self._nhc_reject], dtype=np.int64)
        model, settings = self.kernel_parts()
        run_span(imu, self.arrays(), model, settings, self.nhc_settings(), fixes, carry, rows, pv)
        self.t = float(imu.t[-1])
        self.gate_open = bool(imu.gate[-1])
        self._k, self._consecutive_reject, self._nhc_reject = int(carry[0]), int(carry[1]), int(carry[2])
        used = fixes.status > 0
        for k in np.flatnonzero(~used):
            self.n_rejected += 1
            self.log_rejected(float(fixes.t[k]), float(fixes.nis[k]))
        return used

    def log_rejected(self, t: float, nis: float) -> None:
        """Log a GNSS fix the χ² gate rejected (here and for the online engine's kernel spans)."""
        log.info("GNSS fix at t=%.3f rejected (NIS %.1f > %.1f)", t, nis, self.config.chi2_gate)

    def update_gnss_velocity(self, t: float, vel_ned: np.ndarray, sigma_ned: np.ndarray) -> bool:
        """GNSS antenna velocity fix (NED m/s, 1σ NED m/s) at time t ≤ the filter time
        (:mod:`imunoise.nav.measurements.gnss_velocity`); returns whether the χ² gate let it in."""
        fix = as_gnss_velocity([t], vel_ned, sigma_ned)
        if fix.t.size == 0:
            log.warning("GNSS velocity at t=%.3f is not finite: ignored", t)
            return False
        out = gnss_velocity_update(self.arrays(), *self.kernel_parts(), fix.vel_ned[0], fix.sigma_ned[0], self.lever)
        return self._record("gnss_velocity", t, out)

    def zupt_update(self, sigma_v: float, chi2: float = 0.0) -> bool:
        """Zero-velocity update: v^n = 0 with 1σ ``sigma_v`` (m/s) (:mod:`imunoise.nav.measurements.zupt`).

        Parameters
        ----------
        sigma_v : float
            1σ of the zero velocity [m/s].
        chi2 : float
            Skip the update when its NIS vᵀ(P_vv + σ²I)⁻¹v exceeds this (3 dof); 0 = always apply.

        Returns
        -------
        bool
            Whether the update was applied.
        """
        return self._record("zupt", self.t, zupt_update(self.arrays(), *self.kernel_parts(), float(sigma_v),
                                                        float(chi2)))

    def zaru_update(self, sigma_w: float) -> bool:
        """Zero angular-rate update: corrected ω_ib^b equals the Earth rate in body, 1σ ``sigma_w`` (rad/s).

        Parameters
        ----------
        sigma_w : float
            1σ of the angular rate [rad/s].

        Returns
        -------
        bool
            Whether the update was applied.
        """
        self.flush()
        dt = self.acc[A_LAST_DT] if self.acc[A_LAST_DT] > 0 else self.dt_nom
        L = self.layout
        dz, H, R = zaru(self.nav, self.P.shape[0], dt, L.hvec, L.axis_of, float(sigma_w))
        nis, ok, S, K = kf_update(self.P, self.nav, self.xm, dz, H, R, 0.0, True, 0.0)
        return self._record("zaru", self.t, (nis, ok, dz, S, K))

    # -- model swap -------------------------------------------------------------------------------
    def swap_model(self, axis_models, *, preserve: bool = False, imu_rate_hz: float | None = None) -> dict[str, int]:
        """Replace the error models (SPEC §8 hot-swap); returns ``{"kept": k, "reset": r}``.

        Navigation states and their covariance are kept; the new bias state of each axis takes the
        current total error estimate h·x̂ of the old states with variance h P hᵀ and cross-covariances
        P[:, old] hᵀ (an exact linear map); new AR1 states start at 0 with their stationary variance,
        new DR states at 0 with the configured σ. With ``preserve`` an old AR1/DR state that has a
        counterpart in the new model (same structure: by position; else an AR1 with the same φ) is carried
        over 1:1 instead (:func:`~imunoise.nav.error_states.swap_map`); ``kept`` counts those, ``reset``
        the states that start fresh. ``axis_models``: as for the constructor
        (:func:`~imunoise.nav.defaults.normalize_axis_models`, with ``imu_rate_hz`` as the default rate).

        Parameters
        ----------
        axis_models
            The new error model of each axis.
        preserve : bool
            Carry matching AR1/DR states over instead of resetting them.
        imu_rate_hz : float, optional
            Rate of models given without one (default: the filter's nominal rate).
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
                 gnss_sigma: np.ndarray, *, gate: np.ndarray | None = None, with_nis: bool = False,
                 with_std: bool = False, in_place: bool = False, with_nll: bool = False) -> tuple:
        """Run a copy of the filter on from its current state (the filter itself is not changed, unless
        ``in_place``): the batch kernel of :func:`~imunoise.nav.ekf.run_ekf` over IMU samples ``t[1:]`` (``t[0]``
        must be the filter time) with the fixes ``gnss_*`` (sorted; σ as given). Used to rehearse a GNSS outage on data
        already seen and to run shadow filters (:mod:`imunoise.online.motion_noise`); the result equals
        :meth:`propagate`/:meth:`update_gnss` called sample by sample.

        Parameters
        ----------
        t : numpy.ndarray
            Sample times [s], ``t[0]`` = the filter time, increasing.
        dtheta, dv : numpy.ndarray
            (n, 3) increments [rad, m/s]; row k covers (t[k−1], t[k]] (row 0 is not used).
        gnss_t, gnss_llh, gnss_sigma : numpy.ndarray
            Fixes to apply (times [s], (m, 3) lat/lon rad, h m, (m, 3) 1σ NED m); may be empty.
        gate : numpy.ndarray, optional
            Angular-rate gate per sample (default closed).
        with_nis, with_nll, with_std : bool
            Also return the NIS, then the innovation NLL (:class:`Fixes`), of every fix (NaN where not reached),
            then the 1σ of δr, δv, φ at every sample, (n, 9) (NED m, m/s, rad).
        in_place : bool
            Advance this filter itself to ``t[-1]`` (``last_innovation`` is not updated).

        Returns
        -------
        tuple of numpy.ndarray
            ``(llh, euler)`` of the IMU point at every sample, (n, 3) each, followed by ``nis`` with
            ``with_nis``, ``nll`` with ``with_nll`` and ``std`` with ``with_std``.
        """
        t = np.ascontiguousarray(t, dtype=float)
        if t.size < 2 or abs(t[0] - self.t) > 1e-9 or np.any(np.diff(t) <= 0):
            raise DataError(f"rehearse: t must start at the filter time {self.t:.3f} s and increase")
        self.flush()
        n = t.size
        sv = self.view
        out = new_outputs(n, store_cov=False, has_sf=False)
        out.pos[0], out.vel[0], out.att[0] = sv.llh, sv.vel, nav_euler(self.nav)
        out.std[0] = sv.std_nav
        gt = np.ascontiguousarray(gnss_t, dtype=float)
        gsig = np.maximum(np.ascontiguousarray(gnss_sigma, dtype=float).reshape(-1, 3), self.config.gnss_sigma_floor)
        fixes = Fixes(gt, np.ascontiguousarray(gnss_llh, dtype=float).reshape(-1, 3), gsig, self.lever,
                      np.full(gt.size, -1, dtype=np.int64), np.full(gt.size, np.nan),
                      np.full(gt.size if with_nll else 0, np.nan))
        imu = ImuInput(t, np.ascontiguousarray(dtheta, dtype=float), np.ascontiguousarray(dv, dtype=float),
                       np.zeros(n, dtype=np.bool_) if gate is None else np.ascontiguousarray(gate, dtype=np.bool_),
                       np.zeros(n, dtype=np.bool_))
        f = self.arrays() if in_place else FilterArrays(*(a.copy() for a in self.arrays()))
        run_batch(imu, f, *self.kernel_parts(), self.nhc_settings(), fixes, velocity_fixes(None, self.lever), out)
        if in_place:
            self.t = float(t[-1])
        extra = [a for a, w in ((fixes.nis, with_nis), (fixes.nll, with_nll), (out.std, with_std)) if w]
        return (out.pos, out.att, *extra)

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
