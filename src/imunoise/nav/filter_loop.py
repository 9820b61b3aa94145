"""The filter engine (issue 23, 31): one step sequence for every path into the filter, and its update functions.

:func:`run_steps` is the step sequence: per IMU sample the strapdown and covariance propagation with the
non-holonomic constraint (:func:`predict_step`), the due epochs of every measurement stream
(:mod:`imunoise.nav.streams`: GNSS position, GNSS velocity, ...) through :func:`stream_update`, the zero-velocity
update, the outputs. It runs from the sample in its ``carry`` to a given stop, so one kernel serves the batch
run (:func:`~imunoise.nav.ekf.run_ekf`), the online engine's spans between events
(:meth:`~imunoise.nav.ekf.LooselyCoupledEKF.run_span`), rehearsals, the noise-schedule pieces
(:mod:`imunoise.nav.noise_schedule`) and, through :func:`predict_step`, the step filter's single
:meth:`~imunoise.nav.ekf.LooselyCoupledEKF.propagate`. Each update propagates the covariance to the current
epoch, builds (dz, H, R) with the measurement's function (:mod:`imunoise.nav.measurements`) and runs the one
:func:`~imunoise.nav.ekf_kernels.kf_update`, so a batch run and the step filter fed sample by sample give the
same trajectory to the bit (``tests/nav/test_nav_filter_step.py``, ``tests/nav/test_engine_reference.py``).

The kernel takes small typed tuples (numba reads a ``NamedTuple`` of arrays as one argument) built in one
place, :meth:`LooselyCoupledEKF.kernel_parts`: :class:`FilterArrays` (the state, changed in place),
:class:`ModelArrays` (the error-model layout), :class:`Settings` (gates and σ), :class:`ImuInput`, the streams
and :class:`Outputs`. Callers outside ``nav`` use the filter's methods instead (``run_span``, ``rehearse``,
``update``, :func:`~imunoise.nav.noise_schedule.run_pieces`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from imunoise.nav.earth import dcm_to_euler
from imunoise.nav.ekf_kernels import kf_update, nav_step, propagate_cov, sensor_errors_into, std_nav
from imunoise.nav.measurements.gnss_position import gnss_position
from imunoise.nav.measurements.nhc import nhc, nhc_gate
from imunoise.nav.measurements.zupt import zupt
from imunoise.nav.mechanization import quat_euler, quat_to_dcm
from imunoise.nav.state import A_LAST_DT, A_STEPS, I_POS, I_Q, I_VEL, N_NAV, X_VEL
from imunoise.nav.streams import C_CHI2, C_GATE_ABS, C_MAX_REJECT, S_NEXT, S_REJECT, measure

__all__ = [
    "FilterArrays", "ModelArrays", "Settings", "ImuInput", "Outputs", "new_outputs", "span_outputs", "innovation_nll",
    "flush",
    "gnss_position_update", "zupt_update", "nhc_due", "nhc_update", "fix_status", "stream_update", "predict_step",
    "next_due",
    "run_steps", "C_NEXT", "C_SAMPLES", "C_NHC_REJECT", "SPAN_COLS", "next_event", "euler_rows",
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


SPAN_COLS = 1 + 3 + 3 + 4 + 6 + N_NAV
"""Columns of a span row (:class:`Outputs` ``rows``): t, llh, NED velocity, quaternion, sensor errors (6),
1σ of δr, δv, φ (9)."""


class Outputs(NamedTuple):
    """What the engine writes per IMU sample; each array is written only when it has one row per output sample
    (else it is a placeholder and skipped): position, velocity, Euler angles, sensor errors, 1σ of δr, δv, φ,
    the 9×9 navigation covariance, scale factors, span rows (:data:`SPAN_COLS` layout: the online engine's
    stored epoch) and the velocity covariance (the stop guard's input)."""

    pos: np.ndarray
    vel: np.ndarray
    att: np.ndarray
    err: np.ndarray
    std: np.ndarray
    cov: np.ndarray
    sf: np.ndarray
    rows: np.ndarray = np.zeros((0, SPAN_COLS))
    pv: np.ndarray = np.zeros((0, 3, 3))


def new_outputs(n: int, *, store_cov: bool, has_sf: bool) -> Outputs:
    """Empty per-sample outputs of :func:`run_steps` for ``n`` samples."""
    return Outputs(np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 6)), np.empty((n, N_NAV)),
                   np.zeros((n if store_cov else 1, N_NAV, N_NAV)), np.zeros((n if has_sf else 1, 6)))


def span_outputs(rows: np.ndarray, pv: np.ndarray) -> Outputs:
    """Outputs that keep only the span rows and the velocity covariance (the online engine's chunks)."""
    return Outputs(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 6)), np.zeros((0, N_NAV)),
                   np.zeros((0, N_NAV, N_NAV)), np.zeros((0, 6)), rows, pv)


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


@njit(cache=True)
def stream_update(f, m, s, st, i, tk):
    """Epoch ``i`` of stream ``st`` (:mod:`imunoise.nav.streams`) at filter time ``tk``: propagate P to now, build
    (dz, H, R) (:func:`~imunoise.nav.streams.measure`), the one update with the stream's gate (forced in after
    ``cfg[C_MAX_REJECT]`` consecutive rejections); writes the epoch's status, NIS (and NLL) and the stream's
    counters; returns ``(nis, used, dz, S, K)``."""
    flush(f, m, s)
    dz, H, R = measure(f.nav, f.P.shape[0], f.acc[A_LAST_DT], st, i, tk)
    chi2 = st.cfg[C_CHI2]
    mr = st.cfg[C_MAX_REJECT]
    force = mr >= 0.0 and st.state[S_REJECT] >= mr
    nis, ok, S, K = kf_update(f.P, f.nav, f.xm, dz, H, R, chi2, force, st.cfg[C_GATE_ABS])
    st.nis[i] = nis
    if st.nll.shape[0] == st.t.shape[0]:
        st.nll[i] = innovation_nll(dz, S)
    st.status[i] = fix_status(ok, force, chi2, nis)
    st.state[S_REJECT] = 0 if ok else st.state[S_REJECT] + 1
    return nis, ok, dz, S, K


@njit(cache=True, inline="always")  # inlined into run_steps: no call with ~100 flattened arguments per sample
def predict_step(f, m, s, nh, dth, dv, dt, gate, carry, std, rec):
    """The first half of one filter step: the strapdown with the sample's increments, the covariance every
    ``cov_every`` samples (or after a gap), then the non-holonomic constraint when due. ``carry``: as
    :func:`run_steps`; ``std`` follows P. Returns ``(nhc applied, nis, used)``; ``rec`` = (dz, S, K) buffers
    receive the NHC's innovation, its covariance and gain when they have its shape (the step filter's record;
    the loop passes empty ones: no copy, and no array returned per sample)."""
    nav_step(f.nav, f.xm, f.acc, dth, dv, dt, m.hvec, m.axis_of, gate, m.sf_idx)
    carry[C_SAMPLES] += 1
    if f.acc[A_STEPS] >= s.cov_every or dt > 1.5 * s.dt_nom * s.cov_every:
        flush(f, m, s)
        std_nav(f.P, std)
    if nhc_due(f, nh, carry[C_SAMPLES]):
        nis, ok, dz, S, K = nhc_update(f, m, s, nh, carry[C_NHC_REJECT])
        carry[C_NHC_REJECT] = 0 if ok else carry[C_NHC_REJECT] + 1
        std_nav(f.P, std)
        if rec[0].shape[0] == dz.shape[0]:
            rec[0][:] = dz
            rec[1][:, :] = S
            rec[2][:, :] = K
        return True, nis, ok
    return False, 0.0, False


@njit(cache=True)
def next_due(streams):
    """The earliest time of a pending epoch over ``streams`` (inf when none)."""
    t = np.inf
    for st in streams:
        i = st.state[S_NEXT]
        if i < st.t.shape[0] and st.t[i] < t:
            t = st.t[i]
    return t


C_NEXT, C_SAMPLES, C_NHC_REJECT = 0, 1, 2
"""``carry`` of :func:`run_steps` (int64): next sample index of ``imu``, samples propagated so far (the NHC and
ZUPT phase), consecutive NHC rejections."""


@njit(cache=True, nogil=True)  # nogil: rehearsals run in a worker thread beside the filter
def run_steps(imu, f, m, s, nh, streams, carry, out, row0, k_end):
    """The filter's one step sequence, over samples ``carry[C_NEXT]`` … ``k_end − 1`` of ``imu`` (stopping there:
    the caller's next event). Per sample k: :func:`predict_step` (strapdown, covariance, NHC), then every epoch
    of every stream (:mod:`imunoise.nav.streams`) with t ≤ t[k], in stream order, through
    :func:`stream_update`, then the zero-velocity update where ``imu.zupt[k]`` (every ``s.zupt_every``
    samples), then the outputs of row k − ``row0`` (:class:`Outputs`). Batch runs, the online engine's spans,
    rehearsals, noise-schedule pieces and the step filter's :meth:`~imunoise.nav.ekf.LooselyCoupledEKF.propagate`
    all go through it (the last through :func:`predict_step` alone)."""
    t = imu.t
    n_out = t.shape[0] - row0
    std = np.empty(N_NAV)
    std_nav(f.P, std)
    none = (np.empty(0), np.empty((0, 0)), np.empty((0, 0)))
    t_due = next_due(streams)  # the streams are visited only at samples where one is due
    for k in range(carry[C_NEXT], k_end):
        predict_step(f, m, s, nh, imu.dth[k], imu.dv[k], t[k] - t[k - 1], imu.gate[k], carry, std, none)
        if t[k] >= t_due:
            for st in streams:
                while st.state[S_NEXT] < st.t.shape[0] and st.t[st.state[S_NEXT]] <= t[k]:
                    stream_update(f, m, s, st, st.state[S_NEXT], t[k])
                    std_nav(f.P, std)
                    st.state[S_NEXT] += 1
            t_due = next_due(streams)
        if imu.zupt[k] and carry[C_SAMPLES] % s.zupt_every == 0:
            zupt_update(f, m, s, s.zupt_sigma, 0.0)
            std_nav(f.P, std)
        r = k - row0
        if out.pos.shape[0] == n_out:
            for i in range(3):
                out.pos[r, i] = f.nav[I_POS + i]
                out.vel[r, i] = f.nav[I_VEL + i]
            out.att[r, 0], out.att[r, 1], out.att[r, 2] = quat_euler(f.nav[I_Q], f.nav[I_Q + 1], f.nav[I_Q + 2],
                                                                     f.nav[I_Q + 3])
            sensor_errors_into(f.xm, m.hvec, m.axis_of, out.err[r])
            for i in range(N_NAV):
                out.std[r, i] = std[i]
        if out.cov.shape[0] == n_out:
            out.cov[r] = f.P[0:N_NAV, 0:N_NAV]
        if out.sf.shape[0] == n_out:
            for a in range(6):
                out.sf[r, a] = f.xm[m.sf_idx[a]]
        if out.rows.shape[0] == n_out:
            w = out.rows[r]
            w[0] = t[k]
            for i in range(10):
                w[1 + i] = f.nav[I_POS + i]
            sensor_errors_into(f.xm, m.hvec, m.axis_of, w[11:17])
            w[17:26] = std
        if out.pv.shape[0] == n_out:
            for i in range(3):
                for j in range(3):
                    out.pv[r, i, j] = f.P[X_VEL + i, X_VEL + j]
    carry[C_NEXT] = k_end


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
def euler_rows(q):
    """Euler angles (roll, pitch, yaw; rad) of each quaternion row of ``q`` (n, 4), as the per-sample outputs
    compute them (``dcm_to_euler(quat_to_dcm(q))``), in one call."""
    out = np.empty((q.shape[0], 3))
    for k in range(q.shape[0]):
        out[k] = dcm_to_euler(quat_to_dcm(q[k]))
    return out
