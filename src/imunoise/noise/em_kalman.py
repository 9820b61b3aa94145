"""The EM baseline's state-space form and E-step (Stebler et al. 2011; docs/guide/theory.rst, 'Baselines';
:mod:`imunoise.noise.em` runs the
iterations): one sensor axis as AR1 and RW states with WN as the observation noise and an optional deterministic
drift (:func:`state_form`), the Kalman filter and Rauch–Tung–Striebel smoother with the lag-one covariance and
the sufficient statistics of the M-step (:func:`kalman_estep`, numba, steady-state covariances frozen once their
relative change is below 1e-12), and the exact Gaussian log-likelihood (:func:`kalman_loglik`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from imunoise.errors import ModelError
from imunoise.noise.model import Model

__all__ = ["kalman_estep", "kalman_loglik", "state_form"]

_FREEZE_RTOL = 1e-12


@njit(cache=True)
def kalman_estep(y, tt, omega, phi, q, r, p0):  # pragma: no cover - compiled
    """Kalman filter + RTS smoother for y_t = Σ x_t + ω tt_t + v_t, x_{t} = diag(φ) x_{t−1} + e_t.

    Returns loglik, S00, S11, S10 (per state), sum of E[(y − Hx − ω tt)²], Σ tt (y − Hx̂).
    """
    n = y.shape[0]
    k = phi.shape[0]
    xp = np.zeros((n, k))
    xf = np.zeros((n, k))
    cap = min(n, 1 << 17)
    Pp = np.zeros((cap, k, k))
    Pf = np.zeros((cap, k, k))
    P = np.zeros((k, k))
    for i in range(k):
        P[i, i] = p0[i]
    x = np.zeros(k)
    ll = 0.0
    frozen = -1  # first index whose covariances equal the steady state
    Pcur = P.copy()
    Pfc = np.zeros((k, k))
    Kg = np.zeros(k)
    F = 0.0
    for t in range(n):
        if t > 0:
            for i in range(k):
                x[i] = phi[i] * xf[t - 1, i]
        xp[t] = x
        if frozen < 0:
            if t > 0:
                # P_p = Φ P_f Φᵀ + Q with diagonal Φ
                for i in range(k):
                    for j in range(k):
                        Pcur[i, j] = phi[i] * Pfc[i, j] * phi[j]
                    Pcur[i, i] += q[i]
            F = r
            for i in range(k):
                s = 0.0
                for j in range(k):
                    s += Pcur[i, j]
                Kg[i] = s
                F += s
            for i in range(k):
                Kg[i] /= F
            for i in range(k):
                for j in range(k):
                    Pfc[i, j] = Pcur[i, j] - Kg[i] * F * Kg[j]
            if t < cap:
                Pp[t] = Pcur
                Pf[t] = Pfc
            if t > 0 and t < cap:
                num = 0.0
                den = 0.0
                for i in range(k):
                    for j in range(k):
                        d = Pcur[i, j] - Pp[t - 1, i, j]
                        num += d * d
                        den += Pcur[i, j] * Pcur[i, j]
                if num <= (_FREEZE_RTOL * _FREEZE_RTOL) * den or t == cap - 1:
                    frozen = t
        hx = 0.0
        for i in range(k):
            hx += x[i]
        v = y[t] - omega * tt[t] - hx
        ll += -0.5 * (math.log(2.0 * math.pi * F) + v * v / F)
        for i in range(k):
            xf[t, i] = x[i] + Kg[i] * v
    # backward pass
    xs = xf[n - 1].copy()
    Ps = Pf[min(n - 1, cap - 1)].copy() if frozen < 0 or n - 1 < frozen else Pf[frozen].copy()
    S00 = np.zeros(k)
    S11 = np.zeros(k)
    S10 = np.zeros(k)
    e2 = 0.0
    ty = 0.0
    # t = n-1 contributions
    hx = 0.0
    hph = 0.0
    for i in range(k):
        hx += xs[i]
        for j in range(k):
            hph += Ps[i, j]
    e = y[n - 1] - omega * tt[n - 1] - hx
    e2 += e * e + hph
    ty += tt[n - 1] * (y[n - 1] - hx)
    Jm = np.zeros((k, k))
    Pnew = np.zeros((k, k))
    tmp = np.zeros((k, k))
    xnew = np.zeros(k)
    ps_frozen = False
    j_const = False  # J is constant where both P_f[t] and P_p[t+1] are the frozen steady state
    for t in range(n - 2, -1, -1):
        steady = frozen >= 0 and t >= frozen
        a = t if not steady else frozen
        b = t + 1 if (frozen < 0 or t + 1 < frozen) else frozen
        Pft = Pf[a]
        Ppt1 = Pp[b]
        if not (steady and j_const):
            # J = P_f Φᵀ P_p⁻¹
            inv = np.linalg.inv(Ppt1)
            for i in range(k):
                for j in range(k):
                    s = 0.0
                    for m in range(k):
                        s += Pft[i, m] * phi[m] * inv[m, j]
                    Jm[i, j] = s
            j_const = steady
        # pair (t+1, t): Cov(x_{t+1}, x_t | Y) = P_s[t+1] Jᵀ, with Ps = P_s[t+1], xs = x_s[t+1]
        for i in range(k):
            c = 0.0
            for m in range(k):
                c += Ps[i, m] * Jm[i, m]
            S10[i] += c
            S11[i] += Ps[i, i] + xs[i] * xs[i]
        for i in range(k):
            s = 0.0
            for j in range(k):
                s += Jm[i, j] * (xs[j] - xp[t + 1, j])
            xnew[i] = xf[t, i] + s
        for i in range(k):
            S10[i] += xs[i] * xnew[i]
        if not (steady and ps_frozen):
            for i in range(k):
                for j in range(k):
                    s = 0.0
                    for m in range(k):
                        s += Jm[i, m] * (Ps[m, j] - Ppt1[m, j])
                    tmp[i, j] = s
            num = 0.0
            den = 0.0
            for i in range(k):
                for j in range(k):
                    s = 0.0
                    for m in range(k):
                        s += tmp[i, m] * Jm[j, m]
                    Pnew[i, j] = Pft[i, j] + s
                    d = Pnew[i, j] - Ps[i, j]
                    num += d * d
                    den += Pnew[i, j] * Pnew[i, j]
            ps_frozen = steady and t > frozen and num <= (_FREEZE_RTOL * _FREEZE_RTOL) * den
            for i in range(k):
                for j in range(k):
                    Ps[i, j] = Pnew[i, j]
        for i in range(k):
            xs[i] = xnew[i]
        hx = 0.0
        hph = 0.0
        for i in range(k):
            S00[i] += Ps[i, i] + xs[i] * xs[i]
            hx += xs[i]
            for j in range(k):
                hph += Ps[i, j]
        e = y[t] - omega * tt[t] - hx
        e2 += e * e + hph
        ty += tt[t] * (y[t] - hx)
    return ll, S00, S11, S10, e2, ty


def kalman_loglik(y: np.ndarray, model: Model) -> float:
    """Exact Gaussian log-likelihood of de-meaned ``y`` under a state-space model (AR1s, RW, WN, DR)."""
    y = np.ascontiguousarray(np.asarray(y, dtype=float) - np.mean(y))
    phi, q, r, p0, omega, _ = state_form(model, float(np.var(y)))
    tt = np.arange(y.size, dtype=float) - (y.size - 1) / 2.0
    return float(kalman_estep(y, tt, omega, phi, q, r, p0)[0])


def state_form(model: Model, var_y: float) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, float, list[str]]:
    phis, qs, p0s, labels = [], [], [], []
    r = 0.0
    omega = 0.0
    has_wn = False
    for name, c in zip(model.component_names(), model.components):
        if c.kind == "AR1":
            phi, s2 = c.values
            phis.append(phi)
            qs.append(s2)
            p0s.append(s2 / (1.0 - phi * phi))
            labels.append(name)
        elif c.kind == "RW":
            phis.append(1.0)
            qs.append(c.values[0])
            p0s.append(100.0 * var_y)
            labels.append("RW")
        elif c.kind == "WN":
            r = c.values[0]
            has_wn = True
        elif c.kind == "DR":
            omega = c.values[0]
        else:
            raise ModelError(
                f"the EM baseline handles AR1, RW, WN and DR; {c.kind} has no state-space form here "
                "(drop it from --model)"
            )
    if not has_wn:
        raise ModelError("the EM state-space form needs WN as its observation noise; add WN to the model")
    return np.array(phis), np.array(qs), r, np.array(p0s), omega, labels
