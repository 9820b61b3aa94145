"""The filter's numba kernels (docs/guide/theory.rst, 'Navigation filter'): strapdown step with compensation, covariance
propagation and the one
Joseph update with χ² gate (:func:`kf_update`) every measurement goes through (:mod:`imunoise.nav.measurements`).
The step sequence is :func:`imunoise.nav.filter_loop.run_steps`. The equations are in :mod:`imunoise.nav.ekf`;
here they are plain loops over small arrays, kept apart from the stateful filter as KF-GINS keeps its
mechanization apart from its engine. Array layouts: :mod:`imunoise.nav.state`.

Plain-loop linear algebra: the matrices are small and sparse-ish, and loops keep the JIT compile short
(numba's generic `@`/LAPACK paths cost tens of seconds of compilation for no speed gain here).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.nav.earth import OMEGA_E, gravity, radii
from imunoise.nav.mechanization import dcm9, quat_mul, rotvec_to_quat, strapdown
from imunoise.nav.state import (
    A_CDT,
    A_CDTH,
    A_CDV,
    A_DVN,
    A_GATE,
    A_LAST_DT,
    A_STEPS,
    A_T,
    ACC_LEN,
    I_Q,
    I_VEL,
    N_NAV,
    X_ATT,
    X_VEL,
)

__all__ = ["ACC_LEN", "nav_step", "propagate_cov", "kf_update", "feedback", "sensor_errors_of",
           "sensor_errors_into", "std_nav"]


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
def sensor_errors_into(xm, hvec, axis_of, e):
    """:func:`sensor_errors_of` written into ``e`` (6,), e.g. an output row (no array per sample)."""
    for a in range(6):
        e[a] = 0.0
    for s in range(xm.shape[0]):
        e[axis_of[s]] += hvec[s] * xm[s]


@njit(cache=True)
def sensor_errors_of(xm, hvec, axis_of):
    """Current total error estimate of the six axes: e_a = Σ_{s ∈ a} h_s x̂_s (rad/s, m/s²)."""
    e = np.zeros(6)
    sensor_errors_into(xm, hvec, axis_of, e)
    return e


@njit(cache=True)
def _sf(c, xm, k):
    """Increment ``c`` with the scale factor of state ``k`` removed (÷ (1 + x̂_k)); unchanged when k < 0."""
    return c / (1.0 + xm[k]) if k >= 0 else c


@njit(cache=True)
def nav_step(nav, xm, acc, dth, dv, dt, hvec, axis_of, gate, sf_idx):
    """Correct one increment with the current error estimate (bias, then scale factor where ``sf_idx``
    has a state), run the strapdown, accumulate for Φ. On scalars (small arrays cost more to allocate than to
    compute with), in the operations and order of the array form."""
    e0 = e1 = e2 = e3 = e4 = e5 = 0.0  # e_a = Σ_{s ∈ a} h_s x̂_s; e_a + 0.0 = e_a (e_a is never −0.0)
    for s in range(xm.shape[0]):
        a, v = axis_of[s], hvec[s] * xm[s]
        e0, e1, e2 = e0 + (v if a == 0 else 0.0), e1 + (v if a == 1 else 0.0), e2 + (v if a == 2 else 0.0)
        e3, e4, e5 = e3 + (v if a == 3 else 0.0), e4 + (v if a == 4 else 0.0), e5 + (v if a == 5 else 0.0)
    t0, t1, t2 = _sf(dth[0] - e0 * dt, xm, sf_idx[0]), _sf(dth[1] - e1 * dt, xm, sf_idx[1]), _sf(
        dth[2] - e2 * dt, xm, sf_idx[2])
    u0, u1, u2 = _sf(dv[0] - e3 * dt, xm, sf_idx[3]), _sf(dv[1] - e4 * dt, xm, sf_idx[4]), _sf(
        dv[2] - e5 * dt, xm, sf_idx[5])
    C0 = dcm9(nav[I_Q], nav[I_Q + 1], nav[I_Q + 2], nav[I_Q + 3])
    d0, d1, d2 = strapdown(nav, t0, t1, t2, u0, u1, u2, dt)
    C1 = dcm9(nav[I_Q], nav[I_Q + 1], nav[I_Q + 2], nav[I_Q + 3])
    acc[A_DVN] += d0
    acc[A_DVN + 1] += d1
    acc[A_DVN + 2] += d2
    for i in range(3):
        for j in range(3):
            acc[A_CDT + 3 * i + j] += 0.5 * (C0[3 * i + j] + C1[3 * i + j]) * dt
    th = (t0, t1, t2)
    uv = (u0, u1, u2)
    for j in range(3):
        if sf_idx[j] >= 0:
            for i in range(3):
                acc[A_CDTH + 3 * i + j] += 0.5 * (C0[3 * i + j] + C1[3 * i + j]) * th[j]
        if sf_idx[3 + j] >= 0:
            for i in range(3):
                acc[A_CDV + 3 * i + j] += 0.5 * (C0[3 * i + j] + C1[3 * i + j]) * uv[j]
    acc[A_T] += dt
    acc[A_STEPS] += 1.0
    if gate:
        acc[A_GATE] = 1.0
    acc[A_LAST_DT] = dt


@njit(cache=True)
def _nav_F(nav, fn):
    """Continuous 9×9 navigation error dynamics F (KF-GINS ``insPropagation``; Shin 2001 Eq. 3.29)."""
    lat, h = nav[0], nav[2]
    vn, ve, vd = nav[I_VEL], nav[I_VEL + 1], nav[I_VEL + 2]
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
    T = acc[A_T]
    if T <= 0.0:
        return
    n = P.shape[0]
    nm = n - N_NAV
    gate = acc[A_GATE] > 0.0
    # nominal steps of the model block (handles clock jitter and gaps alike)
    k = int(T / dt_nom + 0.5)
    if k < 1:
        k = 1
    fn = np.empty(3)
    for i in range(3):
        fn[i] = acc[A_DVN + i] / T
    Cint = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            Cint[i, j] = acc[A_CDT + 3 * i + j]
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
                B[X_ATT + i, s] = -Cint[i, a] * hvec[s]
        else:
            for i in range(3):
                B[X_VEL + i, s] = Cint[i, a - 3] * hvec[s]
    # scale factors: φ ← −∫C diag(ω̂) dt δs_g, δv ← +∫C diag(f̂) dt δs_a (module docstring)
    is_sf = np.zeros(nm, dtype=np.bool_)
    for a in range(3):
        s = sf_idx[a]
        if s >= 0:
            is_sf[s] = True
            for i in range(3):
                B[X_ATT + i, s] = -acc[A_CDTH + 3 * i + a]
        s = sf_idx[3 + a]
        if s >= 0:
            is_sf[s] = True
            for i in range(3):
                B[X_VEL + i, s] = acc[A_CDV + 3 * i + a]
    FB = _mm(FT, B)
    for i in range(9):
        for s in range(nm):
            Phi[i, N_NAV + s] = B[i, s] + 0.5 * FB[i, s]
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
            Phi[N_NAV + i, N_NAV + j] = PhiM[i, j]
    # process noise: white sensor noise through C_b^n, model block
    C = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            C[i, j] = Cint[i, j] / T
    Qd = np.zeros((n, n))
    for sens in range(2):
        off = X_ATT if sens == 0 else X_VEL
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
            Qd[N_NAV + i, N_NAV + j] = QM[i, j] * (1.0 if is_sf[i] or is_sf[j] else qs)
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
        if i != A_LAST_DT:  # the last dt survives (ZARU)
            acc[i] = 0.0


@njit(cache=True)
def feedback(nav, xm, dx):
    """Closed-loop correction with δx = K·dz; resets the error state (KF-GINS ``stateFeedback``)."""
    lat, h = nav[0], nav[2]
    rm, rn = radii(lat)
    nav[0] = lat - dx[0] / (rm + h)
    nav[1] = nav[1] - dx[1] / ((rn + h) * math.cos(lat))
    nav[2] = h + dx[2]
    for i in range(3):
        nav[I_VEL + i] -= dx[X_VEL + i]
    q = quat_mul(rotvec_to_quat(dx[X_ATT : X_ATT + 3]), nav[I_Q : I_Q + 4])
    q = q / np.sqrt(np.sum(q * q))
    for i in range(4):
        nav[I_Q + i] = q[i]
    for i in range(xm.shape[0]):
        xm[i] += dx[N_NAV + i]


@njit(cache=True)
def kf_update(P, nav, xm, dz, H, R, chi2, force, gate_abs):
    """Joseph-form update with χ² gating and closed-loop feedback, the one update of every measurement.

    Returns ``(nis, used, S, K)``: the gating NIS, whether the update was applied, the innovation covariance
    S = HPHᵀ + R before the update and the gain K (n×m; zeros when not applied), as filterpy's
    ``KalmanFilter.update`` keeps ``S`` and ``K`` (the innovation is ``dz`` itself).

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
        return nis, False, S, np.zeros((n, m))
    if chi2 > 0.0 and nis > chi2 and not force:
        return nis, False, S, np.zeros((n, m))
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
    feedback(nav, xm, dx)
    return nis, True, S, K


@njit(cache=True)
def std_nav(P, out):
    """1σ of δr, δv, φ into ``out`` (9,)."""
    for i in range(N_NAV):
        out[i] = math.sqrt(abs(P[i, i]))
