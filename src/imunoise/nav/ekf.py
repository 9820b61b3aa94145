"""Loosely coupled, closed-loop error-state EKF in NED with augmented IMU error states (SPEC §8).

State vector δx = [δr (NED, m), δv (NED, m/s), φ (rad), x_g,x, x_g,y, x_g,z, x_a,x, x_a,y, x_a,z] where
x_s,i are the states of the error model of sensor axis i built by ``model.state_space(dt, freq)``
(bias, one per AR1, DR). Conventions as KF-GINS (Niu/Shin): δr = r̂ − r, δv = v̂ − v,
C_b^n(est) = (I − φ×) C_b^n(true); for the model states δx = x − x̂ so the sensor error of the
corrected output is ω̂ − ω = H δx + white. Error dynamics (Shin 2001 Eq. 3.29, KF-GINS ``insPropagation``):

    δṙ = F_rr δr + δv,   δv̇ = F_vr δr + F_vv δv + (f^n×) φ + C_b^n H_a δx_a,
    φ̇ = F_φr δr + F_φv δv − (ω_in^n×) φ − C_b^n H_g δx_g,    δx_{k+1} = Φ_m δx_k + w_m

WN/QN of an axis enter as white noise of δv (accel) or φ (gyro) with PSD ``white_psd``.

Scale factors (``EkfConfig.scale_factors``; KF-GINS' 21-state filter, its SG/SA states): sensor model
ω̃ = (1 + s_g)ω + b_g, f̃ = (1 + s_a)f + b_a per axis; the increments are compensated as
Δθ̂ = (Δθ − ê_g Δt)/(1 + ŝ_g), Δv̂ = (Δv − ê_a Δt)/(1 + ŝ_a) (KF-GINS ``imuCompensate``); with δs = s − ŝ
the output error is ω̂ − ω ≈ δb + diag(ω̂) δs, so

    δv̇ += C_b^n diag(f̂^b) δs_a,    φ̇ −= C_b^n diag(ω̂^b_ib) δs_g,

(KF-GINS ``insPropagation``: F[V, SA] = C_b^n diag(f), F[PHI, SG] = −C_b^n diag(ω); KF-GINS' feedback
ŝ += δs is the same sign convention as here), integrated exactly over the covariance interval as
Σ C̄ diag(Δv̂) and Σ C̄ diag(Δθ̂) from the increments. The covariance is
propagated every ``cov_every`` samples over the accumulated interval T with Φ = I + FT + ½(FT)² for the
navigation rows (∫C_b^n dt and ∫f^n dt over the interval are accumulated exactly from the increments) and
the exact model block Φ_m^k, Q_m^(k) for k nominal steps; P' = Φ(P + Q/2)Φᵀ + Q/2 (trapezoidal Q).
Updates use the Joseph form evaluated in O(m·n²) as (I − KH)P(I − KH)ᵀ + KRKᵀ; feedback resets δx.

GNSS position (antenna, lever arm l in body FRD): dz = D_R(r̂ + D_R⁻¹C_b^n l − r_gnss) − v̂·(t_k − t_gnss),
H = [I, 0, (C_b^n l)×, 0], applied at the first IMU epoch t_k ≥ t_gnss (the velocity term refers the fix
to t_k, exact to ½·a·δt² < 1 mm at 100 Hz). The χ² gate tests the NIS against ``chi2_gate`` with
``gate_abs_m``² added to S, and accepts a fix after ``gate_max_reject`` consecutive rejections.

Optional measurements (``EkfConfig.aiding``): non-holonomic constraints (:mod:`imunoise.nav.measurements.nhc`),
applied every ``every`` samples right after the propagation and before that sample's GNSS fixes, in the batch
loop and in :meth:`LooselyCoupledEKF.propagate` alike.

Cost (SPEC §13): with ``cov_every = 5`` (the default; 1 is KF-GINS' per-sample propagation, and on the
shared drive both agree to 0.1 mm RMS and < 1 m outage drift) the 548 s drive at 100 Hz takes ≈ 0.2 s
with the 21-state default and ≈ 0.3 s with 4×AR1+DR+RW on six axes (45 states); ΦPΦᵀ is formed through
the non-zeros of Φ only.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from imunoise.errors import DataError, ModelError
from imunoise.nav.defaults import EkfConfig, default_axis_models
from imunoise.nav.ekf_kernels import kf_update, nav_step, propagate_cov, sensor_errors_of
from imunoise.nav.error_states import AXES, ModelLayout, initial_covariance, scale_spec, swap_map
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
    zupt_update,
)
from imunoise.nav.measurements.gnss_velocity import GnssVelocity, as_gnss_velocity
from imunoise.nav.measurements.nhc import NHC_OFF, NhcConfig
from imunoise.nav.measurements.zupt import zaru
from imunoise.nav.mechanization import make_nav, nav_euler
from imunoise.nav.solution import NavSolution
from imunoise.nav.state import (
    A_LAST_DT,
    A_STEPS,
    ACC_LEN,
    I_DTH,
    I_DV,
    I_PREV,
    N_NAV,
    NAV,
    StateView,
)

log = logging.getLogger(__name__)

__all__ = [
    "AXES", "InitialState", "ModelLayout", "LooselyCoupledEKF", "EkfResult", "run_ekf", "normalize_axis_models",
]



# ----------------------------------------------------------------------------------------------------
# model layout
# ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class InitialState:
    """Initial navigation state and sensor biases (IMU point, not the antenna).

    Attributes
    ----------
    t : float
        Time of the state [s].
    llh : numpy.ndarray
        Latitude, longitude [rad], height [m].
    vel_ned : numpy.ndarray
        Velocity NED [m/s].
    euler : numpy.ndarray
        Roll, pitch, yaw [rad].
    gyro_bias : numpy.ndarray
        Initial gyro bias estimate [rad/s] (default zero).
    accel_bias : numpy.ndarray
        Initial accelerometer bias estimate [m/s²] (default zero).
    """

    t: float
    llh: np.ndarray
    vel_ned: np.ndarray
    euler: np.ndarray
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))


def normalize_axis_models(axis_models, freq: float) -> list[tuple[object, float]]:
    """Six (model, freq) pairs (gyro x,y,z, accel x,y,z) from the accepted spellings.

    Accepted: ``None`` (the plain default); a sequence of 6 models or (model, freq) pairs; a dict
    ``{"gyro": m | [mx, my, mz], "accel": ...}``. A model is anything with ``state_space(dt, freq)``;
    without an explicit freq the IMU rate ``freq`` is used (parameters per sample at the fitted rate).
    """
    if axis_models is None:
        return default_axis_models(freq)

    def pair(m):
        if isinstance(m, tuple) and len(m) == 2:
            return m[0], float(m[1] if m[1] else freq)
        return m, float(getattr(m, "freq", None) or freq)

    if isinstance(axis_models, dict):
        out = []
        for sensor in ("gyro", "accel"):
            if sensor not in axis_models:
                raise ModelError(f"axis models need a '{sensor}' entry (one model or three)")
            m = axis_models[sensor]
            ms = list(m) if isinstance(m, list | np.ndarray) else [m] * 3
            if len(ms) != 3:
                raise ModelError(f"'{sensor}' needs one model or three (x, y, z), got {len(ms)}")
            out += [pair(x) for x in ms]
        models = out
    else:
        models = [pair(m) for m in axis_models]
    if len(models) != 6:
        raise ModelError(f"need 6 axis models (gyro x,y,z, accel x,y,z), got {len(models)}")
    for m, _ in models:
        if not hasattr(m, "state_space"):
            raise ModelError(f"axis model {m!r} has no state_space(dt, freq); pass an imunoise Model")
    return models


# ----------------------------------------------------------------------------------------------------
# Python API
# ----------------------------------------------------------------------------------------------------
@dataclass
class EkfResult(NavSolution):
    """Filter output at every IMU epoch (IMU point): llh [rad, rad, m], vel NED, euler, sensor errors.

    ``gyro_error``/``accel_error`` are the total estimated sensor errors (bias + AR1 + ...) in rad/s and
    m/s²; ``std`` the 1σ of [δr (NED), δv, φ]; ``gnss_status`` per GNSS epoch: 1 used, 0 rejected by the
    χ² gate, 2 forced after too many rejections, −1 outside the run.

    Attributes
    ----------
    t : numpy.ndarray
        IMU epochs [s], shape (N,).
    llh : numpy.ndarray
        Latitude, longitude [rad], height [m], shape (N, 3).
    vel_ned : numpy.ndarray
        Velocity NED [m/s], shape (N, 3).
    euler : numpy.ndarray
        Roll, pitch, yaw [rad], shape (N, 3).
    gyro_error : numpy.ndarray
        Estimated total gyro errors [rad/s], shape (N, 3).
    accel_error : numpy.ndarray
        Estimated total accelerometer errors [m/s²], shape (N, 3).
    std : numpy.ndarray
        1σ of [δr (NED, m), δv (m/s), φ (rad)], shape (N, 9).
    gnss_t : numpy.ndarray
        GNSS epochs [s].
    gnss_status : numpy.ndarray
        Status per GNSS epoch (above).
    gnss_nis : numpy.ndarray
        Normalised innovation squared per GNSS epoch.
    elapsed_s : float
        Wall-clock time of the run [s].
    labels : list of str
        Names of the sensor-error states.
    cov : numpy.ndarray or None
        9×9 navigation block of P per epoch (``store_cov=True``), shape (N, 9, 9).
    scale_factors : numpy.ndarray or None
        Estimated scale factors ŝ (gyro x, y, z, accel x, y, z; dimensionless), shape (N, 6), when
        ``EkfConfig.scale_factors``; else None.
    gnss_vel_status : numpy.ndarray or None
        Per GNSS velocity fix (``run_ekf(gnss_vel=...)``): 1 used, 0 rejected by the χ² gate, −1 outside.
    """

    gnss_t: np.ndarray
    gnss_status: np.ndarray
    gnss_nis: np.ndarray
    elapsed_s: float = 0.0
    labels: list[str] = field(default_factory=list)
    cov: np.ndarray | None = None
    scale_factors: np.ndarray | None = None
    gnss_vel_status: np.ndarray | None = None


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


def _velocity_fixes(vel: GnssVelocity | None, lever: np.ndarray) -> VelocityFixes:
    """The kernel's velocity fixes (none: empty arrays)."""
    vel = vel if vel is not None else as_gnss_velocity(np.zeros(0), np.zeros((0, 3)), np.ones(3))
    return VelocityFixes(vel.t, vel.vel_ned, vel.sigma_ned, lever, np.full(vel.t.size, -1, dtype=np.int64),
                         np.full(vel.t.size, np.nan))


def new_outputs(n: int, *, store_cov: bool, has_sf: bool) -> Outputs:
    """Empty per-sample outputs of :func:`~imunoise.nav.filter_loop.run_batch` for ``n`` samples."""
    return Outputs(np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 6)), np.empty((n, N_NAV)),
                   np.zeros((n if store_cov else 1, N_NAV, N_NAV)), np.zeros((n if has_sf else 1, 6)))


class LooselyCoupledEKF:
    """Step-by-step loosely coupled EKF (SPEC §8) for online use; :func:`run_ekf` is the batch form.

    ``propagate(dtheta, dv, t)`` takes one IMU increment over (t_prev, t]; ``update_gnss(t, llh, sigma)``
    a fix at time t ≤ the current filter time (it is referred to the filter epoch with the velocity).

    Parameters
    ----------
    config : EkfConfig
        Noise, gating and update settings.
    axis_models
        Error model of each sensor axis (:func:`normalize_axis_models`): ``None`` for the defaults,
        six models or (model, freq) pairs, or ``{"gyro": ..., "accel": ...}``.
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

    def _nhc(self):
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
            f, nh = self.arrays(), self._nhc()
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
            log.info("GNSS fix at t=%.3f rejected (NIS %.1f > %.1f)", t, nis, self.config.chi2_gate)
        return bool(ok)

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
        the states that start fresh. ``axis_models``: as for the constructor (:func:`normalize_axis_models`,
        with ``imu_rate_hz`` as the default rate).

        Parameters
        ----------
        axis_models
            The new error model of each axis.
        preserve : bool
            Carry matching AR1/DR states over instead of resetting them.
        imu_rate_hz : float, optional
            Rate of models given without one (default: the filter's nominal rate).

        Returns
        -------
        dict
            ``{"kept": k, "reset": r}``, numbers of model states.
        """
        self.flush()
        rate = imu_rate_hz or 1.0 / self.dt_nom
        new = ModelLayout.build(normalize_axis_models(axis_models, rate), self.dt_nom, scale_spec(self.config))
        res = swap_map(self.layout, new, self.xm, self.P, initial_covariance(self.config, new), preserve=preserve)
        self.xm, self.P, self.layout = res.x, res.P, new
        return {"kept": res.kept, "reset": res.reset}

    # -- what-if runs -------------------------------------------------------------------------------
    def rehearse(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, gnss_t: np.ndarray, gnss_llh: np.ndarray,
                 gnss_sigma: np.ndarray, *, gate: np.ndarray | None = None, with_nis: bool = False,
                 with_std: bool = False, in_place: bool = False) -> tuple:
        """Run a copy of the filter on from its current state (the filter itself is not changed, unless
        ``in_place``): the batch kernel of :func:`run_ekf` over IMU samples ``t[1:]`` (``t[0]`` must be the
        filter time) with the fixes ``gnss_*`` (sorted; σ as given). Used to rehearse a GNSS outage on data
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
        with_nis : bool
            Also return the NIS of every fix (NaN where the fix was not reached).
        with_std : bool
            Also return the 1σ of δr, δv, φ at every sample, (n, 9) (NED m, m/s, rad).
        in_place : bool
            Advance this filter itself to ``t[-1]`` (``last_innovation`` is not updated).

        Returns
        -------
        tuple of numpy.ndarray
            ``(llh, euler)`` of the IMU point at every sample, (n, 3) each, followed by ``nis`` with
            ``with_nis`` and ``std`` with ``with_std``.
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
                      np.full(gt.size, -1, dtype=np.int64), np.full(gt.size, np.nan))
        imu = ImuInput(t, np.ascontiguousarray(dtheta, dtype=float), np.ascontiguousarray(dv, dtype=float),
                       np.zeros(n, dtype=np.bool_) if gate is None else np.ascontiguousarray(gate, dtype=np.bool_),
                       np.zeros(n, dtype=np.bool_))
        f = self.arrays() if in_place else FilterArrays(self.nav.copy(), self.xm.copy(), self.P.copy(),
                                                          self.acc.copy())
        run_batch(imu, f, *self.kernel_parts(), self._nhc(), fixes, _velocity_fixes(None, self.lever), out)
        if in_place:
            self.t = float(t[-1])
        return (out.pos, out.att, *((fixes.nis,) if with_nis else ()), *((out.std,) if with_std else ()))

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


def _check_imu(t: np.ndarray, dth: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reject backwards time, drop exact duplicates (logged), replace non-finite samples (logged)."""
    d = np.diff(t)
    if np.any(d < 0):
        i = int(np.flatnonzero(d < 0)[0]) + 1
        raise DataError(
            f"IMU time goes backwards at sample {i} (t={t[i]:.6f} after {t[i - 1]:.6f}); "
            "sort the file or fix the time stamps"
        )
    dup = np.concatenate([[False], d == 0])
    if np.any(dup):
        log.warning("dropping %d IMU samples with duplicated time stamps", int(dup.sum()))
        keep = ~dup
        t, dth, dv = t[keep], dth[keep], dv[keep]
    bad = ~(np.all(np.isfinite(dth), axis=1) & np.all(np.isfinite(dv), axis=1))
    if np.any(bad):
        log.warning("%d IMU samples with NaN/Inf replaced by zero increments", int(bad.sum()))
        dth, dv = dth.copy(), dv.copy()
        dth[bad], dv[bad] = 0.0, 0.0
    if t.size > 2:
        dtm = np.median(np.diff(t))
        gaps = np.flatnonzero(np.diff(t) > 5 * dtm)
        if gaps.size:
            log.warning(
                "IMU has %d gaps longer than 5 samples (first at t=%.3f, %.3f s); the increments "
                "are integrated over the gap as given",
                gaps.size,
                t[gaps[0]],
                np.diff(t)[gaps[0]],
            )
    return t, dth, dv


def _mask_for(mask, t_all: np.ndarray, t: np.ndarray, what: str) -> np.ndarray:
    """A per-sample boolean mask given on the input IMU epochs, resampled to the run's epochs."""
    if mask is None:
        return np.zeros(t.size, dtype=np.bool_)
    mask = np.asarray(mask, dtype=np.bool_)
    if mask.shape != t_all.shape:
        raise DataError(f"{what} mask has {mask.size} entries, the IMU data {t_all.size}")
    idx = np.clip(np.searchsorted(t_all, t), 0, t_all.size - 1)
    return np.ascontiguousarray(mask[idx])


def run_ekf(
    imu,
    gnss,
    init: InitialState,
    config: EkfConfig | None = None,
    axis_models=None,
    *,
    t_end: float | None = None,
    gate: np.ndarray | None = None,
    store_cov: bool = False,
    zupt: np.ndarray | None = None,
    gnss_vel: GnssVelocity | None = None,
) -> EkfResult:
    """Batch loosely coupled EKF over ``imu`` (ImuData, increments) from ``init.t`` with GNSS fixes.

    The loop (strapdown, covariance, updates) runs in one numba kernel. GNSS epochs with non-finite
    positions are dropped and non-finite/zero σ replaced by ``config.gnss_sigma_nan``/floor (logged).
    ``gate`` (bool per IMU sample) marks epochs where the SPEC §7 angular-rate gate is open.
    ``zupt`` (bool per IMU sample, e.g. the static epochs of :func:`imunoise.detect.detect_static`) applies
    a zero-velocity update (σ ``config.zupt_sigma``) every ``config.zupt_every`` samples while true.
    ``store_cov`` keeps the 9×9 navigation block of P at every epoch in ``result.cov`` (for NEES).
    ``gnss_vel``: antenna velocity fixes (:class:`~imunoise.nav.measurements.gnss_velocity.GnssVelocity`, e.g.
    from :func:`~imunoise.nav.measurements.gnss_velocity.as_gnss_velocity`), applied like the position fixes.

    Parameters
    ----------
    imu : ImuData
        IMU increments (:func:`imunoise.io.kfgins.read_imu`), body FRD.
    gnss : GnssData
        GNSS antenna fixes (:func:`imunoise.io.kfgins.read_gnss`).
    init : InitialState
        State at the start time ``init.t`` (inside the IMU record).
    config : EkfConfig, optional
        Filter settings (default ``EkfConfig()``).
    axis_models : optional
        Error model of each sensor axis (:func:`normalize_axis_models`): ``None`` for the defaults,
        six models or (model, freq) pairs, or ``{"gyro": ..., "accel": ...}``.
    t_end : float, optional
        Last epoch [s] (default: the end of the IMU data).
    gate, zupt : numpy.ndarray, optional
        Boolean per IMU sample, as above.
    store_cov : bool
        Keep the navigation covariance per epoch.

    Returns
    -------
    EkfResult

    Raises
    ------
    DataError
        For a start outside the IMU data, backward time, too few samples or a non-finite result.
    """
    import time

    config = config or EkfConfig()
    t_all = np.asarray(imu.t, dtype=float)
    dth_all, dv_all = imu.increments() if hasattr(imu, "increments") else (imu.dtheta, imu.dv)
    if t_all.size < 2:
        raise DataError("IMU data need at least 2 samples")
    if not (t_all[0] <= init.t < t_all[-1]):
        raise DataError(f"start time {init.t:.3f} is outside the IMU data [{t_all[0]:.3f}, {t_all[-1]:.3f}]")
    t1 = t_all[-1] if t_end is None else float(t_end)
    i0 = int(np.searchsorted(t_all, init.t, side="right")) - 1
    i1 = int(np.searchsorted(t_all, t1, side="right"))
    t = t_all[i0:i1].copy()
    t[0] = init.t  # the first increment after init covers (init.t, t[1]] only approximately: split below
    dth = np.ascontiguousarray(dth_all[i0:i1], dtype=float)
    dv = np.ascontiguousarray(dv_all[i0:i1], dtype=float)
    if i0 + 1 < t_all.size and t_all[i0] < init.t:
        # scale the first increment to the part after init.t
        frac = (t_all[i0 + 1] - init.t) / (t_all[i0 + 1] - t_all[i0])
        if dth.shape[0] > 1:
            dth[1] *= frac
            dv[1] *= frac
    t, dth, dv = _check_imu(t, dth, dv)
    if t.size < 2:
        raise DataError(f"no IMU samples between the start {init.t:.3f} and the end {t1:.3f}")
    rate = 1.0 / float(np.median(np.diff(t)))
    ekf = LooselyCoupledEKF(config, axis_models, init, imu_rate_hz=rate)
    ekf.prime(dth[0], dv[0])

    gt = np.asarray(gnss.t, dtype=float)
    gllh = np.asarray(gnss.llh, dtype=float)
    gsig = np.asarray(gnss.sigma_ned, dtype=float).copy()
    okpos = np.all(np.isfinite(gllh), axis=1) & np.isfinite(gt)
    if not np.all(okpos):
        log.warning("dropping %d GNSS epochs with non-finite time or position", int((~okpos).sum()))
        gt, gllh, gsig = gt[okpos], gllh[okpos], gsig[okpos]
    if gt.size > 1 and np.any(np.diff(gt) < 0):
        order = np.argsort(gt, kind="stable")
        log.warning("GNSS epochs not sorted in time: sorted")
        gt, gllh, gsig = gt[order], gllh[order], gsig[order]
    badsig = ~np.isfinite(gsig)
    if np.any(badsig):
        log.warning("%d GNSS σ values are NaN/Inf: using %.1f m", int(badsig.sum()), config.gnss_sigma_nan)
        gsig[badsig] = config.gnss_sigma_nan
    low = gsig < config.gnss_sigma_floor
    if np.any(low):
        log.warning(
            "%d GNSS σ values below %.3f m (zero?): raised to the floor", int(low.sum()), config.gnss_sigma_floor
        )
        gsig = np.maximum(gsig, config.gnss_sigma_floor)
    gate_arr = _mask_for(gate, t_all, t, "gate")
    zupt_arr = _mask_for(zupt, t_all, t, "zupt")

    n = t.size
    L = ekf.layout
    has_sf = bool(np.all(L.scale_index >= 0))
    out = new_outputs(n, store_cov=store_cov, has_sf=has_sf)
    out.pos[0], out.vel[0], out.att[0] = init.llh, init.vel_ned, init.euler
    out.err[0] = ekf.sensor_errors()
    out.std[0] = np.sqrt(np.diag(ekf.P)[NAV])
    out.cov[0] = ekf.view.P_nav
    if has_sf:
        out.sf[0] = ekf.xm[L.scale_index]
    fixes = Fixes(gt, gllh, gsig, ekf.lever, np.full(gt.size, -1, dtype=np.int64), np.full(gt.size, np.nan))
    imu_in = ImuInput(t, dth, dv, gate_arr, zupt_arr)
    vfixes = _velocity_fixes(gnss_vel, ekf.lever)
    model, settings = ekf.kernel_parts()
    nhc = ekf._nhc()
    if not run_batch.signatures:
        # load (or compile) the kernel on a 2-sample copy so elapsed_s measures the filter only
        run_batch(ImuInput(*(a[:2].copy() for a in imu_in)), FilterArrays(*(a.copy() for a in ekf.arrays())),
                  model, settings, nhc, Fixes(*(a.copy() for a in fixes)), VelocityFixes(*(a.copy() for a in vfixes)),
                  Outputs(*(a[:2].copy() for a in out)))
    t0 = time.perf_counter()
    run_batch(imu_in, ekf.arrays(), model, settings, nhc, fixes, vfixes, out)
    elapsed = time.perf_counter() - t0
    g_status = fixes.status
    n_rej = int(np.sum(g_status == 0))
    if n_rej:
        log.info("%d GNSS fixes rejected by the χ² gate (%d forced)", n_rej, int(np.sum(g_status == 2)))
    res = EkfResult(
        t,
        out.pos,
        out.vel,
        out.att,
        out.err[:, :3],
        out.err[:, 3:],
        out.std,
        gt,
        g_status,
        fixes.nis,
        elapsed,
        list(L.labels),
        out.cov if store_cov else None,
        out.sf if has_sf else None,
        vfixes.status if gnss_vel is not None else None,
    )
    for name in ("llh", "vel_ned", "euler"):
        if not np.all(np.isfinite(getattr(res, name))):
            raise DataError(f"EKF produced non-finite {name}; check the inputs (units, time stamps, init)")
    return res
