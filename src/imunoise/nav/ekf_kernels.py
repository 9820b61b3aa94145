"""The filter's numba kernels (SPEC §8): strapdown step with compensation, covariance propagation, Joseph
update, GNSS innovation and the batch loop (:func:`run_batch`) that :func:`imunoise.nav.ekf.run_ekf` and
:meth:`~imunoise.nav.ekf.LooselyCoupledEKF.rehearse` call. The equations are in :mod:`imunoise.nav.ekf`;
here they are plain loops over small arrays, kept apart from the stateful filter as KF-GINS keeps its
mechanization apart from its engine.

Plain-loop linear algebra: the matrices are small and sparse-ish, and loops keep the JIT compile short
(numba's generic `@`/LAPACK paths cost tens of seconds of compilation for no speed gain here).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.nav.earth import OMEGA_E, dcm_to_euler, gravity, radii
from imunoise.nav.mechanization import I_Q, quat_mul, quat_to_dcm, rotvec_to_quat, strapdown_step

__all__ = ["ACC_LEN", "run_batch", "nav_step", "propagate_cov", "kf_update", "gnss_innovation", "sensor_errors_of"]

ACC_LEN = 34  # accumulator: Σ Δv_f^n (3), Σ C dt (9), T, steps, gate, last dt, Σ C diag(Δθ) (9), Σ C diag(Δv) (9)
I_CDTH = 16  # Σ C̄[i, a] Δθ̂_a at 16 + 3i + a (gyro scale-factor coupling)
I_CDV = 25  # Σ C̄[i, a] Δv̂_a at 25 + 3i + a (accel scale-factor coupling)


@njit(cache=True)
def _mm(A, B):
    """A @ B, skipping zeros of A."""
    n, k = A.shape
    m = B.shape[1]
    C = np.zeros((n, m))
    for i in range(n):
        for l in range(k):
            a = A[i, l]
            if a != 0.0:
                for j in range(m):
                    C[i, j] += a * B[l, j]
    return C


@njit(cache=True)
def _mmt(A, B):
    """A @ B.T."""
    n, k = A.shape
    m = B.shape[0]
    C = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for l in range(k):
                s += A[i, l] * B[j, l]
            C[i, j] = s
    return C


@njit(cache=True)
def _mv(A, x):
    """A @ x."""
    n, k = A.shape
    y = np.zeros(n)
    for i in range(n):
        s = 0.0
        for l in range(k):
            s += A[i, l] * x[l]
        y[i] = s
    return y


@njit(cache=True)
def _spd_inv(S):
    """Inverse of a small symmetric positive-definite matrix by Cholesky; NaN matrix if not PD."""
    m = S.shape[0]
    L = np.zeros((m, m))
    for j in range(m):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return np.full((m, m), np.nan)
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, m):
            v = S[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / L[j, j]
    # inverse of L (lower triangular), then S⁻¹ = L⁻ᵀ L⁻¹
    Li = np.zeros((m, m))
    for i in range(m):
        Li[i, i] = 1.0 / L[i, i]
        for j in range(i):
            v = 0.0
            for k in range(j, i):
                v -= L[i, k] * Li[k, j]
            Li[i, j] = v / L[i, i]
    Si = np.zeros((m, m))
    for i in range(m):
        for j in range(m):
            v = 0.0
            for k in range(max(i, j), m):
                v += Li[k, i] * Li[k, j]
            Si[i, j] = v
    return Si


@njit(cache=True)
def sensor_errors_of(xm, hvec, axis_of):
    """Current total error estimate of the six axes: e_a = Σ_{s ∈ a} h_s x̂_s (rad/s, m/s²)."""
    e = np.zeros(6)
    for s in range(xm.shape[0]):
        e[axis_of[s]] += hvec[s] * xm[s]
    return e


@njit(cache=True)
def nav_step(nav, xm, acc, dth, dv, dt, hvec, axis_of, gate, sf_idx):
    """Correct one increment with the current error estimate (bias, then scale factor where ``sf_idx``
    has a state), run the strapdown, accumulate for Φ."""
    e = sensor_errors_of(xm, hvec, axis_of)
    dthc = np.empty(3)
    dvc = np.empty(3)
    for i in range(3):
        dthc[i] = dth[i] - e[i] * dt
        dvc[i] = dv[i] - e[3 + i] * dt
    for i in range(3):
        if sf_idx[i] >= 0:
            dthc[i] = dthc[i] / (1.0 + xm[sf_idx[i]])
        if sf_idx[3 + i] >= 0:
            dvc[i] = dvc[i] / (1.0 + xm[sf_idx[3 + i]])
    C0 = quat_to_dcm(nav[I_Q : I_Q + 4])
    dvn = strapdown_step(nav, dthc, dvc, dt)
    C1 = quat_to_dcm(nav[I_Q : I_Q + 4])
    for i in range(3):
        acc[i] += dvn[i]
    for i in range(3):
        for j in range(3):
            acc[3 + 3 * i + j] += 0.5 * (C0[i, j] + C1[i, j]) * dt
    for j in range(3):
        if sf_idx[j] >= 0:
            for i in range(3):
                acc[I_CDTH + 3 * i + j] += 0.5 * (C0[i, j] + C1[i, j]) * dthc[j]
        if sf_idx[3 + j] >= 0:
            for i in range(3):
                acc[I_CDV + 3 * i + j] += 0.5 * (C0[i, j] + C1[i, j]) * dvc[j]
    acc[12] += dt
    acc[13] += 1.0
    if gate:
        acc[14] = 1.0
    acc[15] = dt


@njit(cache=True)
def _nav_F(nav, fn):
    """Continuous 9×9 navigation error dynamics F (KF-GINS ``insPropagation``; Shin 2001 Eq. 3.29)."""
    lat, h = nav[0], nav[2]
    vn, ve, vd = nav[3], nav[4], nav[5]
    rm, rn = radii(lat)
    rmh, rnh = rm + h, rn + h
    sl, cl = math.sin(lat), math.cos(lat)
    tl = sl / cl
    w = OMEGA_E
    g = gravity(lat, h)
    F = np.zeros((9, 9))
    F[0, 0] = -vd / rmh
    F[0, 2] = vn / rmh
    F[1, 0] = ve * tl / rnh
    F[1, 1] = -(vd + vn * tl) / rnh
    F[1, 2] = ve / rnh
    F[0, 3] = 1.0
    F[1, 4] = 1.0
    F[2, 5] = 1.0
    F[3, 0] = -2 * ve * w * cl / rmh - ve * ve / (rmh * rnh * cl * cl)
    F[3, 2] = vn * vd / (rmh * rmh) - ve * ve * tl / (rnh * rnh)
    F[4, 0] = 2 * w * (vn * cl - vd * sl) / rmh + vn * ve / (rmh * rnh * cl * cl)
    F[4, 2] = (ve * vd + vn * ve * tl) / (rnh * rnh)
    F[5, 0] = 2 * w * ve * sl / rmh
    F[5, 2] = -ve * ve / (rnh * rnh) - vn * vn / (rmh * rmh) + 2 * g / (math.sqrt(rmh * rnh) + h)
    F[3, 3] = vd / rmh
    F[3, 4] = -2 * (w * sl + ve * tl / rnh)
    F[3, 5] = vn / rmh
    F[4, 3] = 2 * w * sl + ve * tl / rnh
    F[4, 4] = (vd + vn * tl) / rnh
    F[4, 5] = 2 * w * cl + ve / rnh
    F[5, 3] = -2 * vn / rmh
    F[5, 4] = -2 * (w * cl + ve / rnh)
    # (f^n ×)
    F[3, 7] = -fn[2]
    F[3, 8] = fn[1]
    F[4, 6] = fn[2]
    F[4, 8] = -fn[0]
    F[5, 6] = -fn[1]
    F[5, 7] = fn[0]
    F[6, 0] = -w * sl / rmh
    F[6, 2] = ve / (rnh * rnh)
    F[7, 2] = -vn / (rmh * rmh)
    F[8, 0] = -w * cl / rmh - ve / (rmh * rnh * cl * cl)
    F[8, 2] = -ve * tl / (rnh * rnh)
    F[6, 4] = 1.0 / rnh
    F[7, 3] = -1.0 / rmh
    F[8, 4] = -tl / rnh
    # −(ω_in^n ×)
    wx = w * cl + ve / rnh
    wy = -vn / rmh
    wz = -w * sl - ve * tl / rnh
    F[6, 7] = wz
    F[6, 8] = -wy
    F[7, 6] = -wz
    F[7, 8] = wx
    F[8, 6] = wy
    F[8, 7] = -wx
    return F


@njit(cache=True)
def propagate_cov(P, nav, xm, acc, phi_pow, q_pow, hvec, axis_of, wpsd, wpsd_fb, q_scale_gate, dt_nom, sf_idx):
    """Propagate P and the model-state estimates over the accumulated interval; reset the accumulator."""
    T = acc[12]
    if T <= 0.0:
        return
    n = P.shape[0]
    nm = n - 9
    gate = acc[14] > 0.0
    # nominal steps of the model block (handles clock jitter and gaps alike)
    k = int(T / dt_nom + 0.5)
    if k < 1:
        k = 1
    fn = np.empty(3)
    for i in range(3):
        fn[i] = acc[i] / T
    Cint = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            Cint[i, j] = acc[3 + 3 * i + j]
    FT = _nav_F(nav, fn)
    for i in range(9):
        for j in range(9):
            FT[i, j] *= T
    Phi = np.zeros((n, n))
    FT2 = _mm(FT, FT)
    for i in range(9):
        for j in range(9):
            Phi[i, j] = FT[i, j] + 0.5 * FT2[i, j]
        Phi[i, i] += 1.0
    # navigation ← model coupling, first order ∫F_nm dt plus ½ F_nn T · (∫F_nm dt)
    B = np.zeros((9, nm))
    for s in range(nm):
        a = axis_of[s]
        if a < 3:
            for i in range(3):
                B[6 + i, s] = -Cint[i, a] * hvec[s]
        else:
            for i in range(3):
                B[3 + i, s] = Cint[i, a - 3] * hvec[s]
    # scale factors: φ ← −∫C diag(ω̂) dt δs_g, δv ← +∫C diag(f̂) dt δs_a (module docstring)
    is_sf = np.zeros(nm, dtype=np.bool_)
    for a in range(3):
        s = sf_idx[a]
        if s >= 0:
            is_sf[s] = True
            for i in range(3):
                B[6 + i, s] = -acc[I_CDTH + 3 * i + a]
        s = sf_idx[3 + a]
        if s >= 0:
            is_sf[s] = True
            for i in range(3):
                B[3 + i, s] = acc[I_CDV + 3 * i + a]
    FB = _mm(FT, B)
    for i in range(9):
        for s in range(nm):
            Phi[i, 9 + s] = B[i, s] + 0.5 * FB[i, s]
    # model block Φ_m^k, Q_m^(k) (repeated for gaps longer than the table)
    kmax = phi_pow.shape[0] - 1
    step = min(k, kmax)
    PhiM = phi_pow[step].copy()
    QM = q_pow[step].copy()
    kk = k - step
    while kk > 0:  # gaps longer than the table
        step = min(kk, kmax)
        QM = _mmt(_mm(phi_pow[step], QM), phi_pow[step])
        for i in range(nm):
            for j in range(nm):
                QM[i, j] += q_pow[step, i, j]
        PhiM = _mm(phi_pow[step], PhiM)
        kk -= step
    for i in range(nm):
        for j in range(nm):
            Phi[9 + i, 9 + j] = PhiM[i, j]
    # process noise: white sensor noise through C_b^n, model block
    C = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            C[i, j] = Cint[i, j] / T
    Qd = np.zeros((n, n))
    for sens in range(2):
        off = 6 if sens == 0 else 3
        for i in range(3):
            for j in range(3):
                acc_ij = 0.0
                for a in range(3):
                    psd = wpsd[3 * sens + a]
                    if gate and wpsd_fb[3 * sens + a] > psd:
                        psd = wpsd_fb[3 * sens + a]
                    acc_ij += C[i, a] * psd * C[j, a]
                Qd[off + i, off + j] = acc_ij * T
    qs = q_scale_gate if gate else 1.0
    for i in range(nm):
        for j in range(nm):
            # the gate's conservative noise is for the sensor noise model, not the scale factors
            Qd[9 + i, 9 + j] = QM[i, j] * (1.0 if is_sf[i] or is_sf[j] else qs)
    # P ← Φ (P + Q/2) Φᵀ + Q/2, with Φ applied through its non-zeros only
    Ph = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            Ph[i, j] = P[i, j] + 0.5 * Qd[i, j]
    cnt = np.zeros(n, dtype=np.int64)
    cols = np.empty((n, n), dtype=np.int64)
    vals = np.empty((n, n))
    for i in range(n):
        c = 0
        for j in range(n):
            v = Phi[i, j]
            if v != 0.0:
                cols[i, c] = j
                vals[i, c] = v
                c += 1
        cnt[i] = c
    M = np.zeros((n, n))
    for i in range(n):
        for c in range(cnt[i]):
            j = cols[i, c]
            v = vals[i, c]
            for l in range(n):
                M[i, l] += v * Ph[j, l]
    for i in range(n):
        for kq in range(i, n):
            s = 0.0
            for c in range(cnt[kq]):
                s += M[i, cols[kq, c]] * vals[kq, c]
            s += 0.5 * Qd[i, kq]
            P[i, kq] = s
            P[kq, i] = s
    # model-state estimates follow their own dynamics (AR1 decay, DR ramp)
    xnew = _mv(PhiM, xm)
    for i in range(nm):
        xm[i] = xnew[i]
    for i in range(ACC_LEN):
        if i != 15:  # the last dt survives (ZARU)
            acc[i] = 0.0


@njit(cache=True)
def _feedback(nav, xm, dx):
    """Closed-loop correction with δx = K·dz; resets the error state (KF-GINS ``stateFeedback``)."""
    lat, h = nav[0], nav[2]
    rm, rn = radii(lat)
    nav[0] = lat - dx[0] / (rm + h)
    nav[1] = nav[1] - dx[1] / ((rn + h) * math.cos(lat))
    nav[2] = h + dx[2]
    for i in range(3):
        nav[3 + i] -= dx[3 + i]
    q = quat_mul(rotvec_to_quat(dx[6:9]), nav[I_Q : I_Q + 4])
    q = q / np.sqrt(np.sum(q * q))
    for i in range(4):
        nav[I_Q + i] = q[i]
    for i in range(xm.shape[0]):
        xm[i] += dx[9 + i]


@njit(cache=True)
def kf_update(P, nav, xm, dz, H, R, chi2, force, gate_abs):
    """Joseph-form update with χ² gating; returns the gating NIS and whether the update was applied.

    The gate tests dzᵀ(S + gate_abs²·I)⁻¹dz against ``chi2``: innovations of the order of ``gate_abs``
    (m) are never outliers, whatever σ the receiver claims (cm-level RTK σ vs. an IMU with timing jitter).

    (I−KH)P(I−KH)ᵀ + KRKᵀ evaluated as M = P − K(HP), P' = M − (MHᵀ)Kᵀ + KRKᵀ: the same matrix
    product in an O(m·n²) order.
    """
    n = P.shape[0]
    m = dz.shape[0]
    HP = _mm(H, P)
    S = _mmt(HP, H) + R
    S = 0.5 * (S + S.T)
    Si = _spd_inv(S)
    Sg = S.copy()
    for i in range(m):
        Sg[i, i] += gate_abs * gate_abs
    nis = dz @ _mv(_spd_inv(Sg), dz)
    if not np.isfinite(nis):
        return nis, False
    if chi2 > 0.0 and nis > chi2 and not force:
        return nis, False
    K = _mm(np.ascontiguousarray(HP.T), Si)
    M = P - _mm(K, HP)
    MH = _mmt(M, H)
    KR = _mm(K, R)
    for i in range(n):
        for j in range(i, n):
            s = M[i, j]
            for a in range(m):
                s += -MH[i, a] * K[j, a] + KR[i, a] * K[j, a]
            P[i, j] = s
    for i in range(n):
        for j in range(i + 1, n):
            P[j, i] = P[i, j]
    dx = _mv(K, dz)
    _feedback(nav, xm, dx)
    return nis, True


@njit(cache=True)
def gnss_innovation(nav, n, z_llh, lever, dt_back):
    """dz = D_R (r̂_ant − r_gnss) − v̂·δt (NED m) and H (3×n) for a fix δt before the filter epoch."""
    lat, h = nav[0], nav[2]
    rm, rn = radii(lat)
    C = quat_to_dcm(nav[I_Q : I_Q + 4])
    lC = _mv(C, lever)
    dz = np.empty(3)
    dz[0] = (lat - z_llh[0]) * (rm + h) + lC[0] - nav[3] * dt_back
    dz[1] = (nav[1] - z_llh[1]) * (rn + h) * math.cos(lat) + lC[1] - nav[4] * dt_back
    dz[2] = -(h - z_llh[2]) + lC[2] - nav[5] * dt_back
    H = np.zeros((3, n))
    for i in range(3):
        H[i, i] = 1.0
    H[0, 7] = -lC[2]
    H[0, 8] = lC[1]
    H[1, 6] = lC[2]
    H[1, 8] = -lC[0]
    H[2, 6] = -lC[1]
    H[2, 7] = lC[0]
    return dz, H


@njit(cache=True)
def _std9(P, out):
    for i in range(9):
        out[i] = math.sqrt(abs(P[i, i]))


@njit(cache=True, nogil=True)  # nogil: rehearsals run in a worker thread beside the filter
def run_batch(
    t,
    dth,
    dv,
    nav,
    xm,
    P,
    acc,
    gt,
    gllh,
    gsig,
    lever,
    gate_arr,
    phi_pow,
    q_pow,
    hvec,
    axis_of,
    wpsd,
    wpsd_fb,
    q_scale_gate,
    dt_nom,
    cov_every,
    chi2,
    max_reject,
    gate_abs,
    out_pos,
    out_vel,
    out_att,
    out_err,
    out_std,
    g_status,
    g_nis,
    out_cov,
    zupt,
    zupt_every,
    zupt_sigma,
    sf_idx,
    out_sf,
):
    """Batch loop: mechanization + covariance propagation + GNSS (and optional ZUPT) updates."""
    nimu = t.shape[0]
    ng = gt.shape[0]
    gi = 0
    while gi < ng and gt[gi] <= t[0]:
        g_status[gi] = -1
        gi += 1
    n_reject = 0
    std = np.empty(9)
    _std9(P, std)
    for k in range(1, nimu):
        dt = t[k] - t[k - 1]
        nav_step(nav, xm, acc, dth[k], dv[k], dt, hvec, axis_of, gate_arr[k], sf_idx)
        if acc[13] >= cov_every or dt > 1.5 * dt_nom * cov_every:
            propagate_cov(P, nav, xm, acc, phi_pow, q_pow, hvec, axis_of, wpsd, wpsd_fb, q_scale_gate, dt_nom, sf_idx)
            _std9(P, std)
        while gi < ng and gt[gi] <= t[k]:
            propagate_cov(P, nav, xm, acc, phi_pow, q_pow, hvec, axis_of, wpsd, wpsd_fb, q_scale_gate, dt_nom, sf_idx)
            dz, H = gnss_innovation(nav, P.shape[0], gllh[gi], lever, t[k] - gt[gi])
            R = np.zeros((3, 3))
            for i in range(3):
                R[i, i] = gsig[gi, i] * gsig[gi, i]
            force = n_reject >= max_reject
            nis, ok = kf_update(P, nav, xm, dz, H, R, chi2, force, gate_abs)
            g_nis[gi] = nis
            if ok:
                g_status[gi] = 2 if force and chi2 > 0.0 and nis > chi2 else 1
                n_reject = 0
            else:
                g_status[gi] = 0
                n_reject += 1
            _std9(P, std)
            gi += 1
        if zupt[k] and k % zupt_every == 0:
            propagate_cov(P, nav, xm, acc, phi_pow, q_pow, hvec, axis_of, wpsd, wpsd_fb, q_scale_gate, dt_nom, sf_idx)
            Hz = np.zeros((3, P.shape[0]))
            for i in range(3):
                Hz[i, 3 + i] = 1.0
            Rz = np.zeros((3, 3))
            dzv = np.empty(3)
            for i in range(3):
                Rz[i, i] = zupt_sigma * zupt_sigma
                dzv[i] = nav[3 + i]
            kf_update(P, nav, xm, dzv, Hz, Rz, 0.0, True, 0.0)
            _std9(P, std)
        for i in range(3):
            out_pos[k, i] = nav[i]
            out_vel[k, i] = nav[3 + i]
        out_att[k] = dcm_to_euler(quat_to_dcm(nav[I_Q : I_Q + 4]))
        out_err[k] = sensor_errors_of(xm, hvec, axis_of)
        out_std[k] = std
        if out_cov.shape[0] == nimu:
            out_cov[k] = P[0:9, 0:9]
        if out_sf.shape[0] == nimu:
            for a in range(6):
                out_sf[k, a] = xm[sf_idx[a]]
    while gi < ng:
        g_status[gi] = -1
        gi += 1
