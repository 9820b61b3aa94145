"""Loosely coupled, closed-loop error-state EKF in NED with augmented IMU error states
(docs/guide/theory.rst, 'Navigation filter').

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

Cost (docs/guide/theory.rst, 'Quality bars'): with ``cov_every = 5`` (the default; 1 is KF-GINS' per-sample propagation,
and on the shared drive both agree to 0.1 mm RMS and < 1 m outage drift) the 548 s drive at 100 Hz takes ≈ 0.2 s
with the 21-state default and ≈ 0.3 s with 4×AR1+DR+RW on six axes (45 states); ΦPΦᵀ is formed through
the non-zeros of Φ only.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from imunoise.errors import DataError
from imunoise.nav.defaults import EkfConfig, normalize_axis_models
from imunoise.nav.error_states import AXES, ModelLayout
from imunoise.nav.filter_loop import FilterArrays, ImuInput, Outputs, run_steps
from imunoise.nav.measurements.gnss_velocity import GnssVelocity
from imunoise.nav.solution import NavSolution
from imunoise.nav.state import NAV, InitialState
from imunoise.nav.step_filter import LooselyCoupledEKF, new_outputs
from imunoise.nav.step_updates import Innovation
from imunoise.nav.streams import Epochs, bind

log = logging.getLogger(__name__)

__all__ = [
    "AXES", "InitialState", "ModelLayout", "LooselyCoupledEKF", "Innovation", "EkfResult", "run_ekf",
    "normalize_axis_models", "check_imu",
]


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
        Per GNSS velocity fix of the deprecated ``run_ekf(gnss_vel=...)``: 1 used, 0 rejected by the χ² gate,
        −1 outside (with ``streams=``: ``stream_status["gnss_velocity"]``).
    stream_status : dict
        Per measurement stream of ``run_ekf(streams=...)`` (by kind): the status of each epoch, as above (2: forced
        in after consecutive rejections).
    gnss_nll : numpy.ndarray or None
        Per GNSS position fix the innovation NLL (``run_ekf(with_nll=True)``; NaN outside the run).
    """

    gnss_t: np.ndarray
    gnss_status: np.ndarray
    gnss_nis: np.ndarray
    elapsed_s: float = 0.0
    labels: list[str] = field(default_factory=list)
    cov: np.ndarray | None = None
    scale_factors: np.ndarray | None = None
    gnss_vel_status: np.ndarray | None = None
    stream_status: dict = field(default_factory=dict)
    gnss_nll: np.ndarray | None = None


def check_imu(t: np.ndarray, dth: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


GNSS_VEL_DEPRECATED = (
    "run_ekf(gnss_vel=...) is deprecated and will be removed in the next release: pass the velocity fixes as a "
    "measurement stream, run_ekf(..., streams=[gnss_velocity_stream(vel)]) with "
    "`from imunoise.nav import gnss_velocity_stream`; their status is then result.stream_status['gnss_velocity']"
)
"""The warning of the deprecated ``gnss_vel`` argument of :func:`run_ekf` (kept for one release)."""


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
    streams: Sequence[Epochs] = (),
    in_motion=None,
    moving: np.ndarray | None = None,
    with_nll: bool = False,
) -> EkfResult:
    """Batch loosely coupled EKF over ``imu`` (ImuData, increments) from ``init.t`` with GNSS fixes.

    The loop (strapdown, covariance, updates) runs in one numba kernel. GNSS epochs with non-finite
    positions are dropped and non-finite/zero σ replaced by ``config.gnss_sigma_nan``/floor (logged).
    ``gate`` (bool per IMU sample) marks epochs where the docs/guide/theory.rst, 'Static detection' angular-rate gate is
    open. ``zupt`` (bool per IMU sample, e.g. the static epochs of :func:`imunoise.detect.detect_static`) applies
    a zero-velocity update (σ ``config.zupt_sigma``) every ``config.zupt_every`` samples while true.
    ``store_cov`` keeps the 9×9 navigation block of P at every epoch in ``result.cov`` (for NEES).
    ``streams``: measurement streams besides the position fixes (:class:`~imunoise.nav.streams.Epochs` of a
    registered kind, one per kind; e.g. from :mod:`imunoise.nav.aiding_sources`), their status per epoch in
    ``result.stream_status``; antenna velocity fixes the caller holds go in as
    ``streams=[gnss_velocity_stream(vel)]`` (:func:`~imunoise.nav.aiding_sources.gnss_velocity_stream`).
    ``gnss_vel``: deprecated (a :class:`DeprecationWarning`; removed in the next release), the same fixes as
    :class:`~imunoise.nav.measurements.gnss_velocity.GnssVelocity`, their status in ``result.gnss_vel_status``.

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
        Error model of each sensor axis (:func:`~imunoise.nav.defaults.normalize_axis_models`): ``None`` for the
        defaults, six models that carry their rate, or ``{"gyro": ..., "accel": ...}`` ((model, freq) pairs:
        deprecated).
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
    t, dth, dv = check_imu(t, dth, dv)
    if t.size < 2:
        raise DataError(f"no IMU samples between the start {init.t:.3f} and the end {t1:.3f}")
    rate = 1.0 / float(np.median(np.diff(t)))
    if in_motion is not None:
        axis_models = in_motion.models
    ekf = LooselyCoupledEKF(config, axis_models, init, imu_rate_hz=rate)
    ekf.prime(dth[0], dv[0])

    # contiguous like the warm-up copies below: a strided column (read_gnss' t) would compile a second kernel
    gt = np.ascontiguousarray(gnss.t, dtype=float)
    gllh = np.ascontiguousarray(gnss.llh, dtype=float)
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
    fixes = ekf.position_stream(gt, gllh, gsig, with_nll=with_nll)
    extra = list(streams)
    if gnss_vel is not None:
        from imunoise.nav.aiding_sources import gnss_velocity_stream

        warnings.warn(GNSS_VEL_DEPRECATED, DeprecationWarning, stacklevel=2)
        extra.append(gnss_velocity_stream(gnss_vel))
    streams = ekf.streams(fixes)
    for e in extra:
        if streams.get(e.kind) is not None:
            raise DataError(f"run_ekf: two streams of kind {e.kind!r}; give one per kind")
        streams.add(bind(e, ekf.lever, config.chi2_gate))
    streams.start_after(t[0])
    imu_in = ImuInput(t, dth, dv, gate_arr, zupt_arr)
    model, settings = ekf.kernel_parts()
    nhc = ekf.nhc_settings()
    if not run_steps.signatures:
        # load (or compile) the kernel on a 2-sample copy so elapsed_s measures the filter only
        warm = tuple(st._replace(status=st.status.copy(), nis=st.nis.copy(), state=st.state.copy())
                     for st in streams.kernel())
        run_steps(ImuInput(*(a[:2].copy() for a in imu_in)), FilterArrays(*(a.copy() for a in ekf.arrays())),
                  model, settings, nhc, warm, np.array([1, 0, 0], dtype=np.int64),
                  Outputs(*(a[:2].copy() for a in out)), 0, 2)
    t0 = time.perf_counter()
    if in_motion is not None:  # the in-motion part while moving, the static part at stops
        from imunoise.nav.moving_run import run_moving

        mv = np.ones(n, dtype=np.bool_) if moving is None else _mask_for(moving, t_all, t, "moving")
        run_moving(ekf, in_motion, imu_in, ekf.arrays(), streams, out, mv)
    else:
        run_steps(imu_in, ekf.arrays(), model, settings, nhc, streams.kernel(), np.array([1, 0, 0], dtype=np.int64),
                  out, 0, n)
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
        streams.get("gnss_velocity").status if gnss_vel is not None else None,
        {e.kind: streams.get(e.kind).status for e in extra},
        fixes.nll if with_nll else None,
    )
    for name in ("llh", "vel_ned", "euler"):
        if not np.all(np.isfinite(getattr(res, name))):
            raise DataError(f"EKF produced non-finite {name}; check the inputs (units, time stamps, init)")
    return res
