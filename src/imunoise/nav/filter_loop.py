"""One filter step, two drivers (docs/guide/theory.rst, 'Navigation filter'; issue 23): the update functions every path
calls, and the batch loop.

:class:`~imunoise.nav.ekf.LooselyCoupledEKF` (the step filter, one call per IMU sample or fix) and
:func:`run_batch` (the numba loop behind :func:`~imunoise.nav.ekf.run_ekf` and
:meth:`~imunoise.nav.ekf.LooselyCoupledEKF.rehearse`) apply a measurement through the same functions here
(:func:`gnss_position_update`, :func:`zupt_update`, ...), each: propagate the covariance to the current epoch,
build (dz, H, R) with the measurement's function (:mod:`imunoise.nav.measurements`), and run the one
:func:`~imunoise.nav.ekf_kernels.kf_update`. So a batch run and the step filter fed sample by sample give the
same trajectory to the bit (``tests/nav/test_nav_filter_step.py``).

The kernel takes small typed tuples (numba reads a ``NamedTuple`` of arrays as one argument) built in one
place, :meth:`LooselyCoupledEKF.kernel_parts`: :class:`FilterArrays` (the state, changed in place),
:class:`ModelArrays` (the error-model layout), :class:`Settings` (gates and σ), :class:`ImuInput`,
:class:`Fixes` and :class:`Outputs`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from imunoise.nav.earth import dcm_to_euler
from imunoise.nav.ekf_kernels import kf_update, nav_step, propagate_cov, sensor_errors_of, std_nav
from imunoise.nav.measurements.gnss_position import gnss_position
from imunoise.nav.measurements.gnss_velocity import gnss_velocity
from imunoise.nav.measurements.nhc import nhc, nhc_gate
from imunoise.nav.measurements.zupt import zupt
from imunoise.nav.mechanization import quat_to_dcm
from imunoise.nav.state import A_LAST_DT, A_STEPS, I_POS, I_Q, I_VEL, N_NAV, X_VEL

__all__ = [
    "FilterArrays", "ModelArrays", "Settings", "ImuInput", "Fixes", "VelocityFixes", "Outputs", "innovation_nll",
    "flush", "gnss_position_update", "gnss_velocity_update", "zupt_update", "nhc_due", "nhc_update", "fix_status",
    "run_batch", "run_span", "SPAN_COLS", "next_event", "euler_rows",
]


class FilterArrays(NamedTuple):
    """The filter state, updated in place: ``nav`` (17), model states ``xm``, covariance ``P``, accumulator
    ``acc`` (layouts: :mod:`imunoise.nav.state`)."""

    nav: np.ndarray
    xm: np.ndarray
    P: np.ndarray
    acc: np.ndarray


class ModelArrays(NamedTuple):
    """The error-model layout (:class:`~imunoise.nav.error_states.ModelLayout`) and the fallback white PSD."""

    phi_pow: np.ndarray
    q_pow: np.ndarray
    hvec: np.ndarray
    axis_of: np.ndarray
    wpsd: np.ndarray
    wpsd_fb: np.ndarray
    sf_idx: np.ndarray


class Settings(NamedTuple):
    """Scalar settings of the loop (from :class:`~imunoise.nav.defaults.EkfConfig`)."""

    q_scale_gate: float
    dt_nom: float
    cov_every: int
    chi2: float
    max_reject: int
    gate_abs: float
    zupt_every: int
    zupt_sigma: float


class ImuInput(NamedTuple):
    """Per IMU sample: times (s), increments Δθ (rad), Δv (m/s) over (t[k−1], t[k]], the angular-rate gate
    and the ZUPT mask."""

    t: np.ndarray
    dth: np.ndarray
    dv: np.ndarray
    gate: np.ndarray
    zupt: np.ndarray


class Fixes(NamedTuple):
    """GNSS position fixes (sorted): times, llh (rad, rad, m), 1σ NED (m), the lever arm (body FRD, m); the
    loop writes ``status`` (1 used, 0 rejected, 2 forced, −1 outside the run) and ``nis`` (the gate's), and the
    batch loop ``nll`` when it has a row per fix (default: none): the one-step innovation −log density
    ½(νᵀS⁻¹ν + log det S + 3 log 2π), S = HPHᵀ + R before the update (:func:`innovation_nll`)."""

    t: np.ndarray
    llh: np.ndarray
    sigma: np.ndarray
    lever: np.ndarray
    status: np.ndarray
    nis: np.ndarray
    nll: np.ndarray = np.zeros(0)  # not written (0 rows) unless the caller asks for it


class VelocityFixes(NamedTuple):
    """GNSS antenna velocity fixes (sorted): times, NED velocity (m/s), 1σ NED (m/s), the lever arm (body FRD,
    m); the loop writes ``status`` (1 used, 0 rejected, −1 outside the run) and ``nis``."""

    t: np.ndarray
    vel: np.ndarray
    sigma: np.ndarray
    lever: np.ndarray
    status: np.ndarray
    nis: np.ndarray


class Outputs(NamedTuple):
    """Per IMU sample (rows); ``cov`` and ``sf`` have one row when not kept."""

    pos: np.ndarray
    vel: np.ndarray
    att: np.ndarray
    err: np.ndarray
    std: np.ndarray
    cov: np.ndarray
    sf: np.ndarray


@njit(cache=True)
def flush(f, m, s):
    """Propagate P and the model states over the increments accumulated since the last propagation."""
    propagate_cov(f.P, f.nav, f.xm, f.acc, m.phi_pow, m.q_pow, m.hvec, m.axis_of, m.wpsd, m.wpsd_fb,
                  s.q_scale_gate, s.dt_nom, m.sf_idx)


@njit(cache=True)
def gnss_position_update(f, m, s, z_llh, sigma, lever, dt_back, force):
    """A GNSS position fix δt = ``dt_back`` before the filter epoch; ``(nis, used, dz, S, K)``."""
    flush(f, m, s)
    dz, H, R = gnss_position(f.nav, f.P.shape[0], z_llh, lever, dt_back, sigma)
    nis, ok, S, K = kf_update(f.P, f.nav, f.xm, dz, H, R, s.chi2, force, s.gate_abs)
    return nis, ok, dz, S, K


@njit(cache=True)
def gnss_velocity_update(f, m, s, z_vel, sigma, lever):
    """A GNSS antenna velocity (:mod:`imunoise.nav.measurements.gnss_velocity`); ``(nis, used, dz, S, K)``."""
    flush(f, m, s)
    dz, H, R = gnss_velocity(f.nav, f.P.shape[0], z_vel, lever, f.acc[A_LAST_DT], sigma)
    nis, ok, S, K = kf_update(f.P, f.nav, f.xm, dz, H, R, s.chi2, False, 0.0)
    return nis, ok, dz, S, K


@njit(cache=True)
def zupt_update(f, m, s, sigma_v, chi2):
    """Zero velocity with 1σ ``sigma_v`` (m/s), skipped when its NIS exceeds ``chi2`` (> 0); ``(nis, used,
    dz, S, K)``."""
    flush(f, m, s)
    dz, H, R = zupt(f.nav, f.P.shape[0], sigma_v)
    nis, ok, S, K = kf_update(f.P, f.nav, f.xm, dz, H, R, chi2, False, 0.0)
    return nis, ok, dz, S, K


@njit(cache=True)
def nhc_due(f, nh, k):
    """Whether sample ``k`` of a run gets a non-holonomic constraint (every ``nh.every`` samples, gated)."""
    return nh.every > 0 and k % nh.every == 0 and nhc_gate(f.nav, f.acc[A_LAST_DT], nh.min_speed,
                                                           nh.max_yaw_rate, nh.max_lat_acc)


@njit(cache=True)
def nhc_update(f, m, s, nh, n_reject):
    """Zero lateral and vertical body velocity (:mod:`imunoise.nav.measurements.nhc`), forced through the χ² gate
    after ``nh.max_reject`` consecutive rejections ``n_reject``; ``(nis, used, dz, S, K)``."""
    flush(f, m, s)
    dz, H, R = nhc(f.nav, f.P.shape[0], nh.sigma_lat, nh.sigma_vert)
    nis, ok, S, K = kf_update(f.P, f.nav, f.xm, dz, H, R, nh.chi2, n_reject >= nh.max_reject, 0.0)
    return nis, ok, dz, S, K


@njit(cache=True)
def innovation_nll(dz, S):
    """−log N(dz; 0, S) = ½(dzᵀS⁻¹dz + log det S + m log 2π) (the prediction-error decomposition's term of one
    fix; the gate's NIS adds gate_abs² to S and is not this quadratic form)."""
    L = np.linalg.cholesky(S)
    z = np.linalg.solve(L, dz)
    return 0.5 * (z @ z + 2.0 * np.sum(np.log(np.diag(L))) + dz.shape[0] * np.log(2.0 * np.pi))


@njit(cache=True)
def fix_status(ok, force, chi2, nis):
    """Status of a GNSS fix: 1 used, 0 rejected by the gate, 2 forced in after too many rejections."""
    if not ok:
        return 0
    return 2 if force and chi2 > 0.0 and nis > chi2 else 1


@njit(cache=True, nogil=True)  # nogil: rehearsals run in a worker thread beside the filter
def run_batch(imu, f, m, s, nh, fx, vfx, out):
    """Batch loop: mechanization + covariance propagation (+ NHC, :class:`~imunoise.nav.measurements.nhc.NhcSettings`
    ``nh``) + GNSS position ``fx`` and velocity ``vfx`` (and optional ZUPT) updates."""
    t = imu.t
    nimu = t.shape[0]
    gt = fx.t
    ng = gt.shape[0]
    gi = 0
    while gi < ng and gt[gi] <= t[0]:
        fx.status[gi] = -1
        gi += 1
    vi = 0
    while vi < vfx.t.shape[0] and vfx.t[vi] <= t[0]:
        vi += 1
    n_reject = 0
    nhc_reject = 0
    std = np.empty(N_NAV)
    std_nav(f.P, std)
    for k in range(1, nimu):
        dt = t[k] - t[k - 1]
        nav_step(f.nav, f.xm, f.acc, imu.dth[k], imu.dv[k], dt, m.hvec, m.axis_of, imu.gate[k], m.sf_idx)
        if f.acc[A_STEPS] >= s.cov_every or dt > 1.5 * s.dt_nom * s.cov_every:
            flush(f, m, s)
            std_nav(f.P, std)
        if nhc_due(f, nh, k):
            ok = nhc_update(f, m, s, nh, nhc_reject)[1]
            nhc_reject = 0 if ok else nhc_reject + 1
            std_nav(f.P, std)
        while gi < ng and gt[gi] <= t[k]:
            force = n_reject >= s.max_reject
            nis, ok, dz, S, _ = gnss_position_update(f, m, s, fx.llh[gi], fx.sigma[gi], fx.lever, t[k] - gt[gi], force)
            fx.nis[gi] = nis
            if fx.nll.shape[0] == ng:
                fx.nll[gi] = innovation_nll(dz, S)
            fx.status[gi] = fix_status(ok, force, s.chi2, nis)
            n_reject = 0 if ok else n_reject + 1
            std_nav(f.P, std)
            gi += 1
        while vi < vfx.t.shape[0] and vfx.t[vi] <= t[k]:
            nis, ok, _, _, _ = gnss_velocity_update(f, m, s, vfx.vel[vi], vfx.sigma[vi], vfx.lever)
            vfx.nis[vi] = nis
            vfx.status[vi] = 1 if ok else 0
            std_nav(f.P, std)
            vi += 1
        if imu.zupt[k] and k % s.zupt_every == 0:
            zupt_update(f, m, s, s.zupt_sigma, 0.0)
            std_nav(f.P, std)
        for i in range(3):
            out.pos[k, i] = f.nav[I_POS + i]
            out.vel[k, i] = f.nav[I_VEL + i]
        out.att[k] = dcm_to_euler(quat_to_dcm(f.nav[I_Q : I_Q + 4]))
        out.err[k] = sensor_errors_of(f.xm, m.hvec, m.axis_of)
        out.std[k] = std
        if out.cov.shape[0] == nimu:
            out.cov[k] = f.P[0:N_NAV, 0:N_NAV]
        if out.sf.shape[0] == nimu:
            for a in range(6):
                out.sf[k, a] = f.xm[m.sf_idx[a]]
    while gi < ng:
        fx.status[gi] = -1
        gi += 1


SPAN_COLS = 1 + 3 + 3 + 4 + 6 + N_NAV
"""Columns of a :func:`run_span` row: t, llh, NED velocity, quaternion, sensor errors (6), 1σ of δr, δv, φ (9)."""


def next_event(k: int, stop: int, sources) -> int:
    """The one place a chunked run decides where the batch kernel stops: the smallest index ≥ ``k`` in any
    of the sorted integer arrays ``sources`` (stop starts/ends, a model swap, a sample needing Python-side
    policy, a noise schedule's change points, ...), or ``stop`` when none lies before it."""
    e = stop
    for src in sources:
        i = int(np.searchsorted(src, k, side="left"))
        if i < src.shape[0] and src[i] < e:
            e = int(src[i])
    return max(e, k)


@njit(cache=True)
def run_span(imu, f, m, s, nh, fx, carry, rows, pv):
    """The step filter's sample loop over one span between events, in one call (the online engine's chunks).

    Sample k ≥ 1 of ``imu`` is one :meth:`~imunoise.nav.ekf.LooselyCoupledEKF.propagate` (with the gate
    ``imu.gate[k]``; NHC counted from ``carry[0]``) followed by :meth:`update_gnss` of every fix of ``fx`` with
    t ≤ t[k] (σ as given: the caller applies the NaN and floor policy), in the step filter's order and
    through the same update functions, so the span equals the per-sample calls to the bit. Row 0 of ``imu`` is
    the filter's current epoch. ``carry`` (int64): samples so far, consecutive GNSS rejections, consecutive NHC
    rejections (read and written). Writes ``fx.status``/``fx.nis``, per sample ``rows[k − 1]`` (:data:`SPAN_COLS`
    layout: the online engine's stored epoch) and, when ``pv`` has a row per sample, the velocity covariance
    (the stop guard's input)."""
    t = imu.t
    nimu = t.shape[0]
    gi = 0
    ng = fx.t.shape[0]
    std = np.empty(N_NAV)
    std_nav(f.P, std)
    for k in range(1, nimu):
        dt = t[k] - t[k - 1]
        nav_step(f.nav, f.xm, f.acc, imu.dth[k], imu.dv[k], dt, m.hvec, m.axis_of, imu.gate[k], m.sf_idx)
        carry[0] += 1
        if f.acc[A_STEPS] >= s.cov_every or dt > 1.5 * s.dt_nom * s.cov_every:
            flush(f, m, s)
            std_nav(f.P, std)
        if nhc_due(f, nh, carry[0]):
            ok = nhc_update(f, m, s, nh, carry[2])[1]
            carry[2] = 0 if ok else carry[2] + 1
            std_nav(f.P, std)
        while gi < ng and fx.t[gi] <= t[k]:
            force = carry[1] >= s.max_reject
            nis, ok, _, _, _ = gnss_position_update(f, m, s, fx.llh[gi], fx.sigma[gi], fx.lever, t[k] - fx.t[gi], force)
            fx.nis[gi] = nis
            fx.status[gi] = fix_status(ok, force, s.chi2, nis)
            carry[1] = 0 if ok else carry[1] + 1
            std_nav(f.P, std)
            gi += 1
        r = rows[k - 1]
        r[0] = t[k]
        for i in range(10):
            r[1 + i] = f.nav[I_POS + i]
        r[11:17] = sensor_errors_of(f.xm, m.hvec, m.axis_of)
        r[17:26] = std
        if pv.shape[0] == nimu - 1:
            for i in range(3):
                for j in range(3):
                    pv[k - 1, i, j] = f.P[X_VEL + i, X_VEL + j]


@njit(cache=True)
def euler_rows(q):
    """Euler angles (roll, pitch, yaw; rad) of each quaternion row of ``q`` (n, 4), as the per-sample outputs
    compute them (``dcm_to_euler(quat_to_dcm(q))``), in one call."""
    out = np.empty((q.shape[0], 3))
    for k in range(q.shape[0]):
        out[k] = dcm_to_euler(quat_to_dcm(q[k]))
    return out
