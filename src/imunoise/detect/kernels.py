"""numba kernel of the static detector (docs/guide/theory.rst, 'Static detection', paper Eq. 9–10): one pass over a
chunk of samples, the state
carried in arrays between calls. The only implementation of the per-epoch test; :class:`imunoise.detect.StaticDetector`
drives it, and :func:`imunoise.detect.detect_static` is that detector fed the record in chunks."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["N_SF", "N_SI", "reset_state", "detector_kernel"]

# State layout (kept in arrays so that a streaming detector can carry it between calls):
#   buf (N, 2)   ring buffer of accel x, y
#   sf  float64: 0 mean_x, 1 mean_y, 2 m2_x, 3 m2_y, 4 T_prev_x, 5 T_prev_y, 6 lam_prev, 7 t_prev
#   si  int64:   0 count in window, 1 ring position, 2 k (static run length), 3 prev static,
#                4 has t_prev, 5 has T_prev, 6 non-finite accel samples so far (never reset)
N_SF, N_SI = 8, 7
"""Lengths of the float (``sf``) and integer (``si``) state vectors."""


@njit(cache=True)
def reset_state(sf, si, lambda0):
    """Empty the window (after a gap or a non-finite sample): the next N samples cannot be static."""
    sf[0] = 0.0
    sf[1] = 0.0
    sf[2] = 0.0
    sf[3] = 0.0
    sf[4] = np.nan
    sf[5] = np.nan
    sf[6] = lambda0
    si[0] = 0
    si[1] = 0
    si[2] = 0
    si[3] = 0
    si[5] = 0


@njit(cache=True)
def detector_kernel(t, accel, gyro, window, lambda0, gate_rate, adaptive, max_gap, buf, sf, si, T, lam, st, gate):
    """Advance the detector state (``buf``, ``sf``, ``si``) over the samples ``t`` (m,), ``accel`` (m, 3),
    ``gyro`` (m, 3) and write the per-epoch statistic ``T`` (m, 2), threshold ``lam`` (m,), raw static test
    ``st`` (m,) and gate ``gate`` (m,). Feeding a record in any split into calls gives the same outputs."""
    n = t.shape[0]
    lo = 0.5 * lambda0
    hi = 2.0 * lambda0
    for i in range(n):
        x = accel[i, 0]
        y = accel[i, 1]
        wnorm = np.sqrt(gyro[i, 0] * gyro[i, 0] + gyro[i, 1] * gyro[i, 1] + gyro[i, 2] * gyro[i, 2])
        if si[4] == 1 and t[i] - sf[7] > max_gap:
            reset_state(sf, si, lambda0)
        sf[7] = t[i]
        si[4] = 1
        gate[i] = not (wnorm <= gate_rate)  # NaN rate → gate open (conservative)
        if not (np.isfinite(x) and np.isfinite(y)):
            si[6] += 1
            reset_state(sf, si, lambda0)
            T[i, 0] = np.nan
            T[i, 1] = np.nan
            lam[i] = lambda0
            st[i] = False
            continue
        pos = si[1]
        if si[0] < window:
            # Welford growth while the window fills
            si[0] += 1
            c = si[0]
            d = x - sf[0]
            sf[0] += d / c
            sf[2] += d * (x - sf[0])
            d = y - sf[1]
            sf[1] += d / c
            sf[3] += d * (y - sf[1])
        else:
            ox = buf[pos, 0]
            oy = buf[pos, 1]
            mx = sf[0] + (x - ox) / window
            sf[2] += (x - ox) * (x - mx + ox - sf[0])
            sf[0] = mx
            my = sf[1] + (y - oy) / window
            sf[3] += (y - oy) * (y - my + oy - sf[1])
            sf[1] = my
        buf[pos, 0] = x
        buf[pos, 1] = y
        pos += 1
        if pos == window:
            pos = 0
        si[1] = pos
        if si[0] == window and pos == 0:
            # exact two-pass recomputation once per lap of the ring buffer (drift control)
            sx = 0.0
            sy = 0.0
            for j in range(window):
                sx += buf[j, 0]
                sy += buf[j, 1]
            sx /= window
            sy /= window
            qx = 0.0
            qy = 0.0
            for j in range(window):
                qx += (buf[j, 0] - sx) ** 2
                qy += (buf[j, 1] - sy) ** 2
            sf[0] = sx
            sf[1] = sy
            sf[2] = qx
            sf[3] = qy
        if si[0] < window:
            T[i, 0] = np.nan
            T[i, 1] = np.nan
            lam[i] = lambda0
            st[i] = False
            continue
        tx = np.sqrt(max(sf[2], 0.0) / (window - 1))
        ty = np.sqrt(max(sf[3], 0.0) / (window - 1))
        if adaptive and si[5] == 1 and si[3] == 1:
            k = si[2]
            jump = max(abs(tx - sf[4]), abs(ty - sf[5]))
            li = (k * sf[6] + 2.0 * lambda0 - jump) / (k + 1)
            li = min(max(li, lo), hi)
        else:
            li = lambda0
        s = tx < li and ty < li
        T[i, 0] = tx
        T[i, 1] = ty
        lam[i] = li
        st[i] = s
        sf[4] = tx
        sf[5] = ty
        sf[6] = li
        si[5] = 1
        si[3] = 1 if s else 0
        si[2] = si[2] + 1 if s else 0
